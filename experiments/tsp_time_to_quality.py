"""Gap to the optimum against wall time (issue 15, item 5), with ACOTSP alongside on the CPU.

Per instance and seed, one ``eaco_jax.minimize`` run of ``GraphEACO`` (``--ants``,
``--local-search``, ``--ls-best-k``) for ``--seconds`` of search after compilation (the
driver's ``max_seconds``; see ``common.run_timed``). The best length after every
chunk gives a curve; the table shows the mean gap over seeds at ``--checkpoints`` seconds,
after compilation and from the call (compile included). With ``--acotsp PATH`` (a binary
built outside this repository) ACOTSP runs each seed for the same time, MMAS with
``--acotsp-ants`` ants and each local search of ``--acotsp-ls`` (ACOTSP 1.03's codes: 1 = 2-opt,
2 = 2.5-opt, 3 = 3-opt), one
process at a time: pin with ``taskset -c N`` and compare on the same core. Writes JSON
(device, versions, every trace) and a PNG of the curves.

    taskset -c 1 python experiments/tsp_time_to_quality.py --instances pcb442 a280 \\
        --seconds 10 --checkpoints 1 3 10 --acotsp ~/ACOTSP/acotsp        # CPU, one core
    python experiments/tsp_time_to_quality.py --ants 4096 --data-dir DIR  # GPU
    python experiments/tsp_time_to_quality.py --fresh-process --warm-first --ants 1024 ...
    python experiments/tsp_time_to_quality.py --tables results/gpu/tsp_time_to_quality_h100_*.json
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from common import (
    best_at,
    enable_compile_cache,
    find_instance,
    run_timed,
    t_ci,
    write_results,
)

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_time_to_quality.json"


def acotsp_file(name: str, data_dirs: list[Path] | None) -> Path:
    """The .tsp file ACOTSP reads for an instance."""
    from common import data_dirs as dirs

    from eaco_jax.problems.tsp import DATA_DIR

    for d in [DATA_DIR, *dirs(data_dirs)]:
        if (d / f"{name}.tsp").is_file():
            return d / f"{name}.tsp"
    raise FileNotFoundError(name)


def run_acotsp_trace(binary: Path, tsp: Path, seconds: float, seed: int, ls: int,
                     ants: int) -> dict:
    """One ACOTSP MMAS try with local search ``ls``: its improvements as (time, length)."""
    with tempfile.TemporaryDirectory() as tmp:  # ACOTSP writes report files into its cwd
        out = subprocess.run(
            [str(binary), "-i", str(tsp), "--mmas", "-m", str(ants), "-l", str(ls), "-r", "1",
             "-t", str(seconds), "--seed", str(seed)],
            capture_output=True, text=True, check=True, cwd=tmp).stdout
    trace = [[float(t), int(b), int(it)] for b, it, t in re.findall(
        r"best so far (\d+), iteration: (\d+), time ([\d.]+)", out)]
    final = re.findall(r"Best (\d+), found at iteration (\d+), found at time ([\d.]+)", out)
    if final:
        b, it, t = final[-1]
        trace.append([float(t), int(b), int(it)])
    if not trace:
        raise RuntimeError(f"no result in ACOTSP's output:\n{out[-500:]}")
    trace.sort()
    return {"seed": seed, "best": min(b for _, b, _ in trace),
            "trace": [[t, b, it] for t, b, it in trace]}


def summarize(traces: list[list], optimum: float, checkpoints: list[float],
              offsets: list[float] | None = None) -> dict:
    """Mean gap (%) over runs at each checkpoint; None until every run has a tour (a mean
    over the runs that finished compiling would flatter the slow ones away)."""
    out = {}
    for t in checkpoints:
        gaps = []
        for i, tr in enumerate(traces):
            b = best_at(tr, t - (offsets[i] if offsets else 0.0))
            if b is not None:
                gaps.append(100.0 * (b / optimum - 1.0))
        full = len(gaps) == len(traces)
        out[str(t)] = {"mean_gap_percent": statistics.mean(gaps) if full else None,
                       "ci95_percent": list(t_ci(gaps)) if full and len(gaps) > 1 else None,
                       "runs_with_result": len(gaps)}
    return out


def from_call(runs: list[dict], optimum: float, checkpoints: list[float]) -> dict:
    """:func:`summarize` on the wall clock since ``minimize`` was called (``trace_from_call``);
    files written before it was recorded: the compute clock shifted by the compile time."""
    if all("trace_from_call" in r for r in runs):
        return summarize([r["trace_from_call"] for r in runs], optimum, checkpoints)
    return summarize([r["trace"] for r in runs], optimum, checkpoints,
                     [r.get("compile_seconds", 0.0) for r in runs])


def run_in_fresh_process(args: argparse.Namespace, name: str, seed: int) -> dict:
    """One seed in a new Python process (same settings and cache folder): the first call of a
    fresh process, as a user's ``eaco tsp`` is, with JAX's caches as warm as they are."""
    opts = {"--ants": args.ants, "--local-search": args.local_search,
            "--ls-best-k": args.ls_best_k, "--ls-moves-per-step": args.ls_moves_per_step,
            "--max-ls-moves": args.max_ls_moves, "--ls-neighbors": args.ls_neighbors,
            "--preset": args.preset,
            "--crossover": args.crossover, "--mutation": args.mutation,
            "--params": args.params, "--chunk": args.chunk, "--seconds": args.seconds,
            "--cache-dir": args.cache_dir}
    argv = [sys.executable, __file__, "--instances", name, "--seeds", "1", "--first-seed",
            str(seed), "--checkpoints", *map(str, args.checkpoints)]
    for flag, value in opts.items():
        if value is not None:
            argv += [flag, str(value)]
    for d in args.data_dir or []:
        argv += ["--data-dir", str(d)]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run.json"
        subprocess.run(argv + ["--out", str(out)], check=True, stdout=subprocess.DEVNULL)
        return json.loads(out.read_text())["rows"][0]["runs"][0]


def tables(paths: list[Path]) -> None:
    """Markdown rows (mean gap and 95% CI at each checkpoint, after compilation and from the
    call) recomputed from the traces of stored result files: the README's tables."""
    for path in paths:
        data = json.loads(path.read_text())
        checkpoints = [float(t) for t in data["rows"][0]["after_compile"]]
        print(f"{path.name} ({data['info']['device']}, jax {data['info']['jax']})")
        for r in data["rows"]:
            traces = [run["trace"] for run in r["runs"]]
            for label, summ in (("after compile", summarize(traces, r["optimum"], checkpoints)),
                                ("from the call", from_call(r["runs"], r["optimum"],
                                                            checkpoints))):
                cells = []
                for t in checkpoints:
                    c = summ[str(t)]
                    if c["mean_gap_percent"] is None:
                        cells.append(f"– ({c['runs_with_result']} of {len(traces)} runs)")
                    else:
                        lo, hi = c["ci95_percent"]
                        cells.append(f"{c['mean_gap_percent']:.3f}% [{lo:.3f}, {hi:.3f}]")
                row = " | ".join(f"@{t:g} s {c}"
                                 for t, c in zip(checkpoints, cells, strict=True))
                print(f"| {r['instance']} | {r['solver']} | {label} | {row} |")


def plot(rows: list[dict], path: Path) -> None:
    """Mean gap curves per instance (log time axis)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    names = sorted({r["instance"] for r in rows})
    fig, axes = plt.subplots(1, len(names), figsize=(5 * len(names), 4), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        for r in (r for r in rows if r["instance"] == name):
            grid = np.geomspace(0.05, r["seconds"], 60)
            mean = []
            for t in grid:
                got = [best_at(run["trace"], t) for run in r["runs"]]
                got = [g for g in got if g is not None]
                mean.append(100 * (np.mean(got) / r["optimum"] - 1) if got else np.nan)
            ax.plot(grid, mean, label=r["solver"])
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=0.1)
        ax.set_xlabel("seconds after compilation")
        ax.set_ylabel("mean gap to optimum (%)")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", nargs="+", default=["pcb442", "rat783", "pr1002", "pr2392"])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seeds first..first+seeds-1 (confirm a screen's choice on fresh seeds)")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--checkpoints", type=float, nargs="+", default=[1, 3, 10, 30])
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--local-search", default="2opt")
    ap.add_argument("--ls-best-k", type=int)
    ap.add_argument("--ls-moves-per-step", type=int,
                    help="2opt / or-2opt: most moves one batched step applies per tour "
                         "(default: GraphEACO's)")
    ap.add_argument("--ls-neighbors", type=int,
                    help="candidates per city the local search scans (default: all 20)")
    ap.add_argument("--max-ls-moves", type=int,
                    help="cap on improving moves per tour and iteration (default: none)")
    ap.add_argument("--preset", default="default", help="GraphEACO preset (default/mmas/paper)")
    ap.add_argument("--crossover", default="auto", help="GraphEACO crossover (auto/erx/none)")
    ap.add_argument("--mutation", default="auto",
                    help="GraphEACO mutation (auto/inversion/none)")
    ap.add_argument("--params", help="GraphParams overrides, KEY=VALUE,... (as eaco --params)")
    ap.add_argument("--chunk", type=int, default=5)
    ap.add_argument("--acotsp", type=Path, help="ACOTSP binary (built outside the repository)")
    ap.add_argument("--acotsp-ls", type=int, nargs="+", default=[1, 3],
                    help="ACOTSP local searches: 1 = 2-opt, 2 = 2.5-opt, 3 = 3-opt")
    ap.add_argument("--acotsp-ants", type=int, default=25)
    ap.add_argument("--data-dir", type=Path, action="append")
    ap.add_argument("--cache-dir", type=Path, default=Path("out/jax_cache"))
    ap.add_argument("--fresh-process", action="store_true",
                    help="run every seed in its own new process (the first call of a process; "
                         "'from the call' then includes everything a fresh process compiles)")
    ap.add_argument("--warm-first", action="store_true",
                    help="with --fresh-process: one unmeasured process first, so every measured "
                         "one starts with warm caches")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--tables", type=Path, nargs="+",
                    help="print the README's rows from stored result files and stop")
    args = ap.parse_args()
    if args.tables:
        tables(args.tables)
        return
    enable_compile_cache(args.cache_dir)
    from eaco_jax.runs.base import params_with, parse_overrides
    from eaco_jax.strategies.graph_eaco import GraphEACO

    strategy = GraphEACO(num_ants=args.ants, local_search=args.local_search,
                         ls_best_k=args.ls_best_k, crossover=args.crossover,
                         mutation=args.mutation, preset=args.preset,
                         max_ls_moves=args.max_ls_moves, ls_neighbors=args.ls_neighbors,
                         ls_moves_per_step=args.ls_moves_per_step
                         or GraphEACO.ls_moves_per_step)
    overrides = parse_overrides(args.params)
    label = f"eaco {args.ants} ants {args.local_search}" + (
        f" best{args.ls_best_k}" if args.ls_best_k else "") + (
        f" mps{args.ls_moves_per_step}" if args.ls_moves_per_step else "") + (
        f" cap{args.max_ls_moves}" if args.max_ls_moves else "") + (
        f" k{args.ls_neighbors}" if args.ls_neighbors else "") + (
        f" {args.preset}" if args.preset != "default" else "") + (
        f" cx {args.crossover}" if args.crossover != "auto" else "") + (
        f" mut {args.mutation}" if args.mutation != "auto" else "") + (
        f" {args.params}" if args.params else "")
    rows = []
    for name in args.instances:
        problem = find_instance(name, args.data_dir)
        runs = []
        if args.fresh_process and args.warm_first:  # fill the caches; not measured
            run_in_fresh_process(args, name, args.first_seed)
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            if args.fresh_process:
                r = run_in_fresh_process(args, name, seed)
            else:
                params = params_with(strategy.default_params(problem), overrides, "--params: ")
                r = run_timed(problem, strategy, seed, args.seconds, args.chunk, params=params)
            runs.append(r)
            print(f"{name:>8} {label} seed {seed}: {100 * (r['best'] / problem.optimum - 1):.3f}%"
                  f" after {r['iterations']} iterations, compile {r['compile_seconds']:.1f} s",
                  flush=True)
        traces = [r["trace"] for r in runs]
        rows.append({"instance": name, "optimum": problem.optimum, "solver": label,
                     "seconds": args.seconds, "seeds": args.seeds,
                     "first_seed": args.first_seed,
                     "after_compile": summarize(traces, problem.optimum, args.checkpoints),
                     "from_call": from_call(runs, problem.optimum, args.checkpoints),
                     "mean_compile_seconds": statistics.mean(r["compile_seconds"]
                                                             for r in runs),
                     "runs": runs})
        if args.acotsp:
            tsp = acotsp_file(name, args.data_dir)
            for ls in args.acotsp_ls:
                aruns = [run_acotsp_trace(args.acotsp, tsp, args.seconds, s + 1, ls,
                                          args.acotsp_ants) for s in range(args.seeds)]
                tr = [r["trace"] for r in aruns]
                rows.append({"instance": name, "optimum": problem.optimum,
                             "solver": f"ACOTSP MMAS {args.acotsp_ants} ants -l {ls}",
                             "seconds": args.seconds, "seeds": args.seeds,
                             "after_compile": summarize(tr, problem.optimum, args.checkpoints),
                             "from_call": summarize(tr, problem.optimum, args.checkpoints),
                             "mean_compile_seconds": 0.0, "runs": aruns})
                final = statistics.mean(100 * (r["best"] / problem.optimum - 1) for r in aruns)
                print(f"{name:>8} {rows[-1]['solver']}: final mean gap {final:.3f}%", flush=True)
    head = "".join(f"{f'@{t:g}s':>9}" for t in args.checkpoints)
    print(f"\nmean gap % after compilation (from the call, compile included, in brackets)\n"
          f"{'instance':>8} {'solver':>34}{head} {'compile s':>9}")
    for r in rows:
        cells = ""
        for t in args.checkpoints:
            a = r["after_compile"][str(t)]["mean_gap_percent"]
            cells += f"{a:9.3f}" if a is not None else f"{'-':>9}"
        print(f"{r['instance']:>8} {r['solver']:>34}{cells} {r['mean_compile_seconds']:9.1f}")
        cells = ""
        for t in args.checkpoints:
            a = r["from_call"][str(t)]["mean_gap_percent"]
            cells += f"{f'({a:.3f})':>9}" if a is not None else f"{'(-)':>9}"
        print(f"{'':>8} {'':>34}{cells}")
    write_results(args.out, rows)
    png = args.out.with_suffix(".png")
    plot(rows, png)
    print(f"wrote {args.out} and {png}")


if __name__ == "__main__":
    main()
