"""Ablation of every EACO mechanism: one command per problem family (issue 14).

    python experiments/ablation.py tsp            # eil51, kroA100; without and with 2-opt
    python experiments/ablation.py constrained    # g01, g09, g10, g13 derivative-free
    python experiments/ablation.py gait           # NAO, 2 s horizon, native MuJoCo
    python experiments/ablation.py tsp --quick    # smoke run (4 seeds, tiny budgets)

**TSP.** GraphEACO cells, each a parameter set (traced switches) or a static operator choice:
every paper mechanism switched on alone against the default ("+X"), the default-on MMAS
mechanisms switched off ("-X"), the paper's configuration (preset "paper": Table 4 values,
every mechanism on) against the default, and the paper configuration with one mechanism off
at a time ("paper -X"), at a fixed number of tours built (ants x iterations). Each cell is one
compiled call with the seeds vmapped and its parameters unbatched, so a switched-off rule is
skipped by lax.cond as in a single run (vmapping the settings too would run both branches of
every switch).
Paired by seed: cell vs its reference (default, or paper for "paper -X"), Wilcoxon
signed-rank on the final tour lengths, Holm-adjusted within each instance x mode. Fixed wall
time: a cell's best at the iteration it reaches in the default cell's compute time (from its
measured seconds per iteration, 25 seeds vmapped, on a shared 2-core machine: indicative),
capped at the tour budget (which a faster cell would exceed).

**Constrained.** ContinuousEACO derivative-free (``repair_steps=0, refine_ants=0``), float64,
each operator off in turn, q0 = 0, Table 3's best setting (q0 = 0.8, rho = 0.3, p_c = 0.6,
p_m = 0.5), and the other constraint orders (Deb, static penalty PEN = 0.3). Success = feasible
with f - f* <= 1e-4 (CEC2006); success performance; paired tests on the error at the budget and
on the evaluations to target (failures rank worst).

**Gait.** ContinuousEACO on the NAO (native MuJoCo, nominal world, ``--horizon`` seconds,
searched from the whole box), each operator off in turn, q0 = 0 and Table 3's best setting;
the metric is each seed's best distance walked; paired Wilcoxon against the default, Holm.

Writes ``experiments/results/ablation_<family>.{json,csv,png}``.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path
from typing import Any

import common as st
import jax
import jax.numpy as jnp
import numpy as np
from common import divisor_chunk, run_cell

import eaco_jax as ea
from eaco_jax.strategies.continuous_eaco import ContinuousEACO
from eaco_jax.strategies.graph_eaco import GraphEACO

RESULTS = Path(__file__).resolve().parent / "results"
TOLERANCE = 1e-4  # CEC2006 success: f - f* <= 1e-4
T, F = jnp.bool_(True), jnp.bool_(False)


def f32(x: float) -> jax.Array:
    return jnp.float32(x)


# --------------------------------------------------------------------------- TSP cells
def tsp_cells(problem: Any, local_search: str, ants: int) -> list[dict[str, Any]]:
    """Cells: name, reference cell, whether ERX/inversion are on, params."""
    d = GraphEACO(num_ants=ants, local_search=local_search).default_params(problem)
    p = GraphEACO(num_ants=ants, local_search=local_search, preset="paper").default_params()
    ops_default = local_search != "none"
    cells = [("default", None, ops_default, d)]
    plus = [
        ("+local update (Eq. 68-70)", dict(use_local_update=T)),
        ("+elitist ants (Eq. 73-74)", dict(use_elitist=T)),
        ("+elitist, deposit condition (Eq. 3-4)", dict(use_elitist=T, use_deposit_condition=T)),
        ("+elitist, adaptive weight (Eq. 5-6)", dict(use_elitist=T, use_adaptive_weight=T)),
        ("+chaos", dict(use_chaos=T)),
        ("+dynamic evaporation", dict(use_evaporation_schedule=T)),
        ("q0 = 0.8 (Table 3)", dict(q0=f32(0.8))),
        ("beta = 5 (Table 4)", dict(beta=f32(5.0))),
        ("tau0 = 1/(n L_nn) (Table 4)", dict(init_at_tau_max=F)),
        ("-restarts", dict(use_restart=F)),
        ("-bounds (Eq. 7)", dict(use_bounds=F)),
    ]
    cells += [(name, "default", ops_default, d.replace(**kw)) for name, kw in plus]
    cells.append(("+ERX/inversion" if not ops_default else "-ERX/inversion", "default",
                  not ops_default, d))
    cells.append(("paper", "default", True, p))
    minus = [
        ("paper -local update", dict(use_local_update=F)),
        ("paper -elitist ants", dict(use_elitist=F)),
        ("paper -deposit condition", dict(use_deposit_condition=F)),
        ("paper -adaptive weight", dict(use_adaptive_weight=F)),
        ("paper -chaos", dict(use_chaos=F)),
        ("paper -dynamic evaporation", dict(use_evaporation_schedule=F)),
        ("paper q0 = 0", dict(q0=f32(0.0))),
        ("paper beta = 2", dict(beta=f32(2.0))),
        ("paper Q = 1", dict(q=f32(1.0))),
        ("paper +restarts", dict(use_restart=T)),
    ]
    cells += [(name, "paper", True, p.replace(**kw)) for name, kw in minus]
    cells.append(("paper -ERX/inversion", "paper", False, p))
    return [dict(name=n, reference=r, ops=o, params=prm) for n, r, o, prm in cells]


def first_hit(history: np.ndarray, target: float) -> np.ndarray:
    """Per row: first iteration (1-based) with best <= target, or -1."""
    hit = history <= target
    return np.where(hit.any(axis=1), hit.argmax(axis=1) + 1, -1)


def run_tsp(args: argparse.Namespace) -> list[dict[str, Any]]:
    seeds = list(range(args.seeds))
    rows: list[dict[str, Any]] = []
    for name in args.instances.split(","):
        problem = ea.problems.load_tsplib(name)
        opt = float(problem.optimum)
        for ls in args.modes.split(","):
            tours = args.tours_2opt if ls != "none" else args.tours_none
            iters = max(1, tours // args.ants)
            cells = tsp_cells(problem, ls, args.ants)
            chunk = divisor_chunk(iters, args.chunks)
            results: dict[str, dict[str, Any]] = {}
            for c in cells:
                ox, om = ("erx", "inversion") if c["ops"] else ("none", "none")
                strategy = GraphEACO(num_ants=args.ants, local_search=ls, crossover=ox,
                                     mutation=om)
                t0 = time.perf_counter()
                r = run_cell(problem, strategy, c["params"], seeds, iters, chunk)
                results[c["name"]] = dict(cell=c, history=r["history"],
                                          spi=r["seconds_per_iteration"])
                print(f"{name} ls={ls} {c['name']}: {time.perf_counter() - t0:.0f} s, "
                      f"{1e3 * r['seconds_per_iteration']:.1f} ms/it, mean gap "
                      f"{100 * (r['history'][:, -1].mean() / opt - 1):.2f} %", flush=True)
            rows += tsp_rows(name, ls, opt, iters, args.ants, cells, results)
            write(args.out, "tsp", rows, args)  # partial results survive an interruption
    return rows


def tsp_rows(name: str, ls: str, opt: float, iters: int, ants: int, cells: list[dict],
             results: dict[str, dict]) -> list[dict[str, Any]]:
    wall_budget = results["default"]["spi"] * iters
    out = []
    for c in cells:
        r = results[c["name"]]
        hist = r["history"]
        final = hist[:, -1]
        it_wall = int(min(iters, max(1, wall_budget // r["spi"])))
        at_wall = hist[:, it_wall - 1]
        hits = first_hit(hist, opt)
        row = dict(family="tsp", instance=name, local_search=ls, cell=c["name"],
                   reference=c["reference"], ants=ants, iterations=iters,
                   tours=iters * ants, seeds=len(final),
                   **{f"gap_{k}": v for k, v in st.summary(100 * (final / opt - 1)).items()
                      if k in ("mean", "ci_low", "ci_high", "median", "min", "max")},
                   success_rate=float(np.mean(final <= opt)),
                   **{f"gap_mean_at_{int(100 * q)}pct": float(np.mean(
                       100 * (hist[:, max(1, int(q * iters)) - 1] / opt - 1)))
                      for q in (0.1, 0.25, 0.5)},
                   mean_iterations_to_optimum=(float(hits[hits > 0].mean())
                                               if (hits > 0).any() else None),
                   seconds_per_iteration=r["spi"], wall_iterations=it_wall,
                   wall_gap_mean=float(np.mean(100 * (at_wall / opt - 1))),
                   final_lengths=final.tolist(), wall_lengths=at_wall.tolist())
        if c["reference"] is not None:
            ref = results[c["reference"]]
            ref_final = ref["history"][:, -1]
            row["delta_gap_mean"] = row["gap_mean"] - float(np.mean(100 * (ref_final / opt - 1)))
            row["p_value"] = st.paired_test(final, ref_final)
            ref_wall = ref["history"][:, int(min(iters, max(1, wall_budget // ref["spi"]))) - 1]
            row["wall_p_value"] = st.paired_test(at_wall, ref_wall)
        out.append(row)
    tested = [r for r in out if "p_value" in r]
    for r, h in zip(tested, st.holm([r["p_value"] for r in tested]), strict=True):
        r["p_holm"] = h
    return out


# --------------------------------------------------------------------------- constrained
def constrained_cells() -> list[dict[str, Any]]:
    d = ContinuousEACO(refine_ants=0, repair_steps=0).default_params()
    cells = [
        ("default (derivative-free)", None, "epsilon", {}),
        ("-Laplace crossover", "default (derivative-free)", "epsilon", dict(p_crossover=0.0)),
        ("-power mutation", "default (derivative-free)", "epsilon", dict(p_mutation=0.0)),
        ("-chaos", "default (derivative-free)", "epsilon", dict(chaos_rate=0.0)),
        ("-chaotic restart", "default (derivative-free)", "epsilon",
         dict(restart_patience=1e9)),
        ("q0 = 0", "default (derivative-free)", "epsilon", dict(q0=0.0)),
        ("Table 3 best (q0 .8, rho .3, pc .6, pm .5)", "default (derivative-free)", "epsilon",
         dict(q0=0.8, rho=0.3, p_crossover=0.6, p_mutation=0.5)),
        ("Deb rules", "default (derivative-free)", "deb", {}),
        ("penalty PEN = 0.3", "default (derivative-free)", "penalty", {}),
    ]
    return [dict(name=n, reference=r, method=m, params=d.replace(**kw))
            for n, r, m, kw in cells]


def run_constrained(args: argparse.Namespace) -> list[dict[str, Any]]:
    seeds = list(range(args.seeds))
    rows: list[dict[str, Any]] = []
    cells = constrained_cells()
    for name in args.problems.split(","):
        with ea.problems.float64():
            problem = ea.problems.cec2006(name)
            results = {}
            for c in cells:
                strategy = ContinuousEACO(refine_ants=0, repair_steps=0,
                                          constraint_method=c["method"])
                iters = args.budget // strategy.num_ants
                t0 = time.perf_counter()
                r = run_cell(problem, strategy, c["params"], seeds, iters,
                             divisor_chunk(iters, args.chunks), stop=_all_hit)
                s = r["state"]
                te = np.asarray(s.target_evaluations)
                err = np.asarray(s.best_f) - problem.f_star
                err = np.where(np.asarray(s.best_violation) > 0, np.inf, np.maximum(err, 0.0))
                results[c["name"]] = dict(te=te, err=err)
                print(f"{name} {c['name']}: {r['iterations']} it, "
                      f"{time.perf_counter() - t0:.0f} s, success {np.mean(te >= 0):.2f}",
                      flush=True)
        rows += constrained_rows(name, problem.f_star, args.budget, cells, results)
        write(args.out, "constrained", rows, args)
    return rows


def _all_hit(state: Any) -> bool:
    return bool(np.all(np.asarray(state.target_evaluations) >= 0))


def constrained_rows(name: str, f_star: float, budget: int, cells: list[dict],
                     results: dict[str, dict]) -> list[dict[str, Any]]:
    out = []
    for c in cells:
        r = results[c["name"]]
        te, err = r["te"], r["err"]
        ok = te >= 0
        row = dict(family="constrained", problem=name, f_star=f_star, cell=c["name"],
                   reference=c["reference"], method=c["method"], budget=budget,
                   seeds=len(te), success_rate=float(ok.mean()),
                   success_performance=st.success_performance(np.where(ok, te, -1)),
                   mean_evals_successful=float(te[ok].mean()) if ok.any() else None,
                   feasible_rate=float(np.mean(np.isfinite(err))),
                   **{f"error_{k}": v for k, v in st.summary(err).items()},
                   evaluations_to_target=[int(x) if x >= 0 else None for x in te],
                   final_errors=[float(x) if np.isfinite(x) else None for x in err])
        out.append(row)
    return retest_constrained(out)


def retest_constrained(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Paired tests of each cell against its reference, from the per-seed lists: the error
    at the budget (errors <= 1e-4 are successes and tie at 0; infeasible runs rank worst) and
    the evaluations to target (failures rank worst); Holm-adjusted per problem."""
    for prob in dict.fromkeys(r["problem"] for r in rows):
        sel = [r for r in rows if r["problem"] == prob]
        by_name = {r["cell"]: r for r in sel}

        def err(r: dict) -> np.ndarray:
            e = np.array([np.inf if v is None else v for v in r["final_errors"]])
            return np.where(e <= TOLERANCE, 0.0, e)

        def evals(r: dict) -> np.ndarray:
            return np.array([np.inf if v is None else v for v in r["evaluations_to_target"]])

        tested = [r for r in sel if r["reference"] is not None]
        for r in tested:
            ref = by_name[r["reference"]]
            r["p_error"] = st.paired_test(err(r), err(ref))
            r["p_evaluations"] = st.paired_test(evals(r), evals(ref))
            r["better_seeds"] = int(np.sum(err(r) < err(ref)))
            r["worse_seeds"] = int(np.sum(err(r) > err(ref)))
        for key in ("p_error", "p_evaluations"):
            for r, h in zip(tested, st.holm([r[key] for r in tested]), strict=True):
                r[key + "_holm"] = h
    return rows


# --------------------------------------------------------------------------- outputs
# --------------------------------------------------------------------------- gait
def gait_cells() -> list[dict[str, Any]]:
    """ContinuousEACO's operators on the NAO gait (derivative-free: the gait has no gradient)."""
    d = ContinuousEACO(refine_ants=0, repair_steps=0).default_params()
    cells = [
        ("default", None, {}),
        ("-Laplace crossover", "default", dict(p_crossover=0.0)),
        ("-power mutation", "default", dict(p_mutation=0.0)),
        ("-chaos", "default", dict(chaos_rate=0.0)),
        ("-chaotic restart", "default", dict(restart_patience=1e9)),
        ("q0 = 0", "default", dict(q0=0.0)),
        ("Table 3 best (q0 .8, rho .3, pc .6, pm .5)", "default",
         dict(q0=0.8, rho=0.3, p_crossover=0.6, p_mutation=0.5)),
    ]
    return [dict(name=n, reference=r, params=d.replace(**kw)) for n, r, kw in cells]


def run_gait(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Each cell: ``--seeds`` searches from the whole box on native MuJoCo, nominal world,
    ``--horizon`` seconds; the metric is the best distance walked (the paper's fitness)."""
    from eaco_jax.problems.gait import make_gait_problem

    problem = make_gait_problem("nao", backend="native", horizon=args.horizon)
    strategy = ContinuousEACO(num_ants=args.ants, archive_size=args.archive, refine_ants=0,
                              repair_steps=0)
    seeds = list(range(args.seeds))
    rows = []
    for c in gait_cells():
        t0 = time.perf_counter()
        r = run_cell(problem, strategy, c["params"], seeds, args.iterations,
                     divisor_chunk(args.iterations, args.chunks))
        fit = -r["history"]  # best distance so far per seed and iteration
        rows.append(dict(family="gait", problem=f"nao {args.horizon:g} s", cell=c["name"],
                         reference=c["reference"], ants=args.ants,
                         iterations=args.iterations, seeds=len(seeds),
                         **{f"distance_{k}": v for k, v in st.summary(fit[:, -1]).items()},
                         distance_at_half=float(np.mean(fit[:, args.iterations // 2 - 1])),
                         seconds_per_iteration=r["seconds_per_iteration"],
                         final_distances=fit[:, -1].tolist()))
        print(f"gait {c['name']}: {rows[-1]['distance_mean']:.3f} m "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    ref = next(r for r in rows if r["reference"] is None)["final_distances"]
    tested = [r for r in rows if r["reference"] is not None]
    for r in tested:
        r["p"] = st.paired_test(r["final_distances"], ref)
        r["delta_vs_ref"] = r["distance_mean"] - rows[0]["distance_mean"]
        r["better_worse_seeds"] = [int(np.sum(np.array(r["final_distances"]) > ref)),
                                   int(np.sum(np.array(r["final_distances"]) < ref))]
    for r, ph in zip(tested, st.holm([r["p"] for r in tested]), strict=True):
        r["p_holm"] = ph
    write(args.out, "gait", rows, args)
    return rows


def write(stem_dir: str, family: str, rows: list[dict[str, Any]], args: argparse.Namespace):
    from eaco_jax.outputs import to_jsonable

    out = Path(stem_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"ablation_{family}{'_quick' if args.quick else ''}"
    meta = {k: v for k, v in vars(args).items() if k not in ("func",)}
    meta.update(device=str(jax.devices()[0]), jax=jax.__version__,
                cpu_cores=len(__import__("os").sched_getaffinity(0)))
    stem.with_suffix(".json").write_text(
        json.dumps(to_jsonable({"meta": meta, "rows": rows}), indent=1) + "\n")
    lists = {"final_lengths", "wall_lengths", "evaluations_to_target", "final_errors",
             "final_distances", "better_worse_seeds"}
    keys = [k for k in rows[0] if k not in lists]
    for r in rows:
        keys += [k for k in r if k not in keys and k not in lists]
    with stem.with_suffix(".csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: _fmt(r.get(k)) for k in keys})
    plot(stem.with_suffix(".png"), family, rows)


def _fmt(v: Any) -> Any:
    return f"{v:.6g}" if isinstance(v, float) else v


def plot(path: Path, family: str, rows: list[dict[str, Any]]) -> None:
    from eaco_jax import plots

    key = ("instance", "local_search") if family == "tsp" else ("problem", "method")
    panels = sorted({(r[key[0]], r[key[1]] if family == "tsp" else "") for r in rows})
    fig, axes = plots.subplots(1, len(panels), figsize=(5.2 * len(panels), 7.5), squeeze=False)
    for ax, (a, b) in zip(axes[0], panels, strict=True):
        sel = [r for r in rows if r[key[0]] == a and (family != "tsp" or r[key[1]] == b)]
        if family in ("tsp", "gait"):  # a mean with its 95% CI per cell
            m = "gap" if family == "tsp" else "distance"
            mean = [r[f"{m}_mean"] for r in sel]
            lo = [r[f"{m}_mean"] - r[f"{m}_ci_low"] for r in sel]
            hi = [r[f"{m}_ci_high"] - r[f"{m}_mean"] for r in sel]
            pv = [r.get("p_holm") for r in sel]
            if family == "tsp":
                ax.set_xlabel("gap to optimum at the tour budget, % (mean, 95% CI)")
                ax.set_title(f"{a}, {'2-opt' if b != 'none' else 'no local search'}")
            else:
                ax.set_xlabel("best distance walked, m (mean, 95% CI)")
                ax.set_title(a)
        else:
            mean = [r["success_rate"] for r in sel]
            lo = hi = [0.0] * len(sel)
            pv = [r.get("p_evaluations_holm") for r in sel]
            ax.set_xlabel("success rate (feasible, f - f* <= 1e-4)")
            ax.set_title(a)
        y = np.arange(len(sel))
        colors = ["tab:gray" if p is None else ("tab:red" if p < 0.05 else "tab:blue")
                  for p in pv]
        ax.barh(y, mean, xerr=[lo, hi], color=colors, alpha=0.8)
        ax.set_yticks(y, [r["cell"] for r in sel], fontsize=7)
        ax.invert_yaxis()
    fig.suptitle(f"ablation ({family}): red = Holm-adjusted paired Wilcoxon p < 0.05 vs reference")
    plots.save_figure(fig, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="family", required=True)
    t = sub.add_parser("tsp")
    t.add_argument("--instances", default="eil51,kroA100")
    t.add_argument("--modes", default="none,2opt")
    t.add_argument("--ants", type=int, default=25)
    t.add_argument("--tours-none", type=int, default=20_000)
    t.add_argument("--tours-2opt", type=int, default=2_500)
    t.add_argument("--timing-iterations", type=int, default=10)
    c = sub.add_parser("constrained")
    c.add_argument("--problems", default="g01,g09,g10,g13")
    c.add_argument("--budget", type=int, default=100_000)
    g = sub.add_parser("gait")
    g.add_argument("--horizon", type=float, default=2.0)
    g.add_argument("--ants", type=int, default=16)
    g.add_argument("--archive", type=int, default=24)
    g.add_argument("--iterations", type=int, default=24)
    for p in (t, c, g):
        p.add_argument("--seeds", type=int, default=25)
        p.add_argument("--chunks", type=int, default=10, help="compiled chunks per run")
        p.add_argument("--quick", action="store_true", help="smoke run: 4 seeds, tiny budgets")
        p.add_argument("--out", default=str(RESULTS))
        p.add_argument("--note", default="", help="stored in the JSON's meta")
    m = sub.add_parser("merge", help="merge result JSONs of one family into one table")
    m.add_argument("merge_family", choices=("tsp", "constrained"))
    m.add_argument("files", nargs="+")
    m.add_argument("--out", default=str(RESULTS))
    m.add_argument("--note", default="", help="stored in the JSON's meta (e.g. a reduced budget)")
    args = ap.parse_args()
    if args.family == "merge":
        rows, metas = [], []
        for f in args.files:
            d = json.loads(Path(f).read_text())
            rows += d["rows"]
            metas.append(d["meta"])
        args.quick, args.parts = False, metas
        if args.merge_family == "constrained":
            rows = retest_constrained(rows)
        write(args.out, args.merge_family, rows, args)
        print(f"{len(rows)} rows merged under {args.out}")
        return
    if args.quick:
        args.seeds = 4
        if args.family == "tsp":
            args.instances, args.tours_none, args.tours_2opt = "eil51", 500, 100
            args.timing_iterations = 2
        elif args.family == "gait":
            args.iterations, args.horizon = 4, 0.5
        else:
            args.problems, args.budget = "g01", 2_000
    run = {"tsp": run_tsp, "constrained": run_constrained, "gait": run_gait}[args.family]
    rows = run(args)
    print(f"{len(rows)} rows written under {args.out}")


if __name__ == "__main__":
    main()
