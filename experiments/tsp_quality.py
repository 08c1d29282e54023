"""Solution quality of the default graph EACO colony on TSPLIB, over seeds (issue 2's table).

For each instance: mean / min / max gap to the optimum over seeds and the number of seeds that
found the optimum. Small instances (eil51 ... kroA100) run an iteration budget; large ones
(a280, pcb442) run for a wall-clock budget per run (``--time-limit``, 60 s). Seeds are vmapped
into one compiled call; for the timed instances the group of S vmapped seeds runs for
S x time-limit seconds of wall time (the same CPU time as S sequential runs of time-limit each),
and the table reports that per-run equivalent; ``--sequential`` runs each seed alone instead
(``taskset -c 0 ...`` pins a run to one core). Run with and without 2-opt local search.

    python experiments/tsp_quality.py            # full table (long: tens of minutes on 2 cores)
    python experiments/tsp_quality.py --quick    # smoke run: 2 seeds, small budgets
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_quality.json"
SMALL = ["eil51", "berlin52", "st70", "eil76", "kroA100"]
LARGE = ["a280", "pcb442"]


class NextChunkOverLimit:
    """Stop rule: the next chunk, if as long as the last one, would take the run past
    ``limit`` seconds of compute (compilation excluded)."""

    def __init__(self, limit: float) -> None:
        self.limit, self.seconds = limit, 0.0

    def __call__(self, state, progress) -> bool:
        last, self.seconds = progress.seconds - self.seconds, progress.seconds
        return progress.seconds + last > self.limit


def run_group(problem, strategy, seeds, *, iterations=None, time_limit=None, chunk=10):
    """Run vmapped seeds for ``iterations`` or until ``time_limit`` seconds of wall time (after
    compilation) would be exceeded by the next chunk. Returns lengths, iterations, timings."""
    import eaco_jax as ea
    from eaco_jax.problems.tsp import tour_length

    if time_limit is not None:  # the time rule ends the run; the budget is only a bound
        res = ea.minimize(problem, strategy, seed=seeds, iterations=10**9, chunk_size=chunk,
                          stop=NextChunkOverLimit(time_limit))
    else:
        res = ea.minimize(problem, strategy, seed=seeds, iterations=iterations,
                          chunk_size=chunk)
    tours = np.asarray(res.best_solution).reshape(len(seeds), -1)
    dist = np.asarray(problem.dist)
    lengths = [int(tour_length(dist, t)) for t in tours]
    return {
        "lengths": lengths,
        "iterations": int(res.iterations),
        "run_seconds": res.seconds - res.compile_seconds,
        "compile_seconds": res.compile_seconds,
        "restarts": np.asarray(res.state.restarts).reshape(-1).tolist(),
    }


def merge_runs(runs: list[dict]) -> dict:
    """One record for several groups of seeds: lengths and restarts concatenated, iterations
    per group listed, seconds summed."""
    if len(runs) == 1:
        return runs[0]
    return {
        "lengths": [x for r in runs for x in r["lengths"]],
        "iterations": [r["iterations"] for r in runs],
        "run_seconds": sum(r["run_seconds"] for r in runs),
        "compile_seconds": sum(r["compile_seconds"] for r in runs),
        "restarts": [x for r in runs for x in r["restarts"]],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: 2 seeds, small budgets")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--large-seeds", type=int, default=None,
                    help="seeds for a280/pcb442 (default: --seeds)")
    ap.add_argument("--iterations", type=int, default=300, help="budget, small, with 2-opt")
    ap.add_argument("--iterations-no-ls", type=int, default=2000, help="budget without 2-opt")
    ap.add_argument("--time-limit", type=float, default=60.0, help="seconds per run, large")
    ap.add_argument("--instances", nargs="+", default=SMALL + LARGE)
    ap.add_argument("--modes", nargs="+", default=["ls", "no-ls"], choices=["ls", "no-ls"])
    ap.add_argument("--timed", nargs="*", default=LARGE,
                    help="instances run for --time-limit seconds instead of an iteration budget")
    ap.add_argument("--sequential", action="store_true",
                    help="run seeds one at a time (each alone for --time-limit seconds) instead "
                         "of vmapped together")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    if args.quick:
        args.seeds, args.iterations, args.iterations_no_ls, args.time_limit = 2, 20, 40, 5.0

    import jax

    from eaco_jax.problems.tsp import load_tsplib
    from eaco_jax.strategies.graph_eaco import GraphEACO

    rows = []
    print(f"{'instance':>9} {'mode':>5} {'seeds':>5} {'iters':>6} {'mean gap%':>9} {'min%':>6} "
          f"{'max%':>6} {'#opt':>4} {'s/run':>7}")
    for mode in args.modes:
        for name in args.instances:
            problem = load_tsplib(name)
            large = name in LARGE
            timed = name in args.timed
            n_seeds = (args.large_seeds or args.seeds) if large else args.seeds
            seeds = list(range(n_seeds))
            strategy = GraphEACO(local_search="2opt" if mode == "ls" else "none")
            groups = [[s] for s in seeds] if args.sequential else [seeds]
            if timed:
                runs = [run_group(problem, strategy, g, time_limit=args.time_limit * len(g),
                                  chunk=5 if mode == "ls" else 20) for g in groups]
            else:
                budget = args.iterations if mode == "ls" else args.iterations_no_ls
                runs = [run_group(problem, strategy, g, iterations=budget,
                                  chunk=max(1, budget // 10)) for g in groups]
            r = merge_runs(runs)
            opt = float(problem.optimum)
            gaps = [100.0 * (length / opt - 1.0) for length in r["lengths"]]
            row = dict(instance=name, n=problem.n, optimum=opt, mode=mode, seeds=n_seeds,
                       mean_gap_percent=float(np.mean(gaps)), min_gap_percent=float(min(gaps)),
                       max_gap_percent=float(max(gaps)),
                       optimum_hits=int(sum(g == 0 for g in gaps)),
                       seconds_per_run=r["run_seconds"] / n_seeds, gaps_percent=gaps, **r)
            rows.append(row)
            iters = r["iterations"]
            iters = int(np.median(iters)) if isinstance(iters, list) else iters
            print(f"{name:>9} {mode:>5} {n_seeds:>5} {iters:>6} "
                  f"{row['mean_gap_percent']:9.3f} {row['min_gap_percent']:6.2f} "
                  f"{row['max_gap_percent']:6.2f} {row['optimum_hits']:>4} "
                  f"{row['seconds_per_run']:7.1f}", flush=True)
            args.out.parent.mkdir(parents=True, exist_ok=True)
            args.out.write_text(json.dumps({
                "device": str(jax.devices()[0]), "cpu_count": os.cpu_count(),
                "quick": args.quick, "strategy": "GraphEACO() defaults", "rows": rows,
                "sequential": args.sequential, "time_limit": args.time_limit,
                "command": "python " + " ".join(sys.argv),
            }, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
