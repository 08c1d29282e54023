"""Gait Pareto fronts: the colony's multi-objective mode against NSGA-II (pymoo), NAO.

Speed x endurance (``--second endurance``) or speed x electrical CoT (``--second cot``) under
the current, slip, drift and fall constraints
(:func:`eaco_jax.problems.gait_mo.make_gait_mo_problem`), at equal evaluations: ``--ants``
ants (= archive = NSGA-II population) x ``--generations``. Both arms evaluate through the same
batched function, ``problem.evaluate(X, key)`` (ants x R worlds in one rollout): the colony
inside its compiled program (``ea.minimize``, all seeds vmapped), NSGA-II through pymoo's
ask-and-tell API with every seed's generation evaluated as one call (the evaluation vmapped
over the seeds, offspring padded to the population size, so one compiled shape serves every
call). On MuJoCo Warp both vmaps size its shared contact buffer for all the seeds
(``GaitProblem.for_rows``). Both see the
optimisation stream of ``--worlds-seed``: the colony's per-iteration key picks each batch
(``optimisation_key``), NSGA-II's key of generation ``t`` is ``fold_in(PRNGKey(seed), t)``;
``--fixed-worlds`` keeps batch 0 for both.

Scores, for each seed and arm (float64, ``eaco_jax.ops.pareto.hypervolume`` w.r.t. the
problem's ``ref_point``, feasible points only):

* ``search``: the final front as the method holds it (its own objectives, from the worlds it
  was last evaluated in): the colony's archive feasible first front, NSGA-II's final
  population's feasible non-dominated points;
* ``rescored``: the final archive / population (``--ants`` points each) re-evaluated in
  ``--score-worlds`` worlds of the *selection* stream (no arm searched on them); the
  hypervolume of the feasible ones. This is the comparison's figure.

Each arm's hypervolumes over the seeds get a bootstrap 95 % CI of the mean; the seed-paired
two-sided Wilcoxon signed-rank test compares the arms (seed s of the colony with seed s of
NSGA-II). Seeds: the colony runs ``MOParams`` defaults (chosen on ZDT1/DTLZ2, not here),
NSGA-II pymoo's defaults; nothing is tuned on these seeds.

    pip install -e '.[mo]'      # pymoo
    # CPU smoke run (proves the harness end to end; no claims from it):
    python experiments/gait_fronts.py --second endurance --backend native --horizon 4 \\
        --worlds 2 --ants 16 --generations 3 --seeds 0-1 --smoke

Writes ``results/gait_fronts/<tag>.json`` and ``<tag>.png`` (one seed's fronts and the
union over seeds), with device, versions, command and date.
"""

from __future__ import annotations

import argparse
import datetime
import sys
import time
from pathlib import Path

import common as st
import jax
import jax.numpy as jnp
import numpy as np
from mo_benchmark import parse_seeds, summarise

import eaco_jax as ea
from eaco_jax.gait.worlds import stream_key
from eaco_jax.ops import pareto
from eaco_jax.problems.gait_mo import make_gait_mo_problem
from eaco_jax.runs.gait import narrowed_around, steering_of, world_ranges
from eaco_jax.strategies import MOEACO

RESULTS = Path(__file__).resolve().parent / "results" / "gait_fronts"
ARMS = ("colony", "nsga2")
LABEL = {"colony": "MOEACO", "nsga2": "NSGA-II (pymoo)"}


def hypervolume(f: np.ndarray, violation: np.ndarray, ref: np.ndarray) -> float:
    """Hypervolume (float64) of the feasible points of ``f`` ``(n, 2)`` w.r.t. ``ref``."""
    ok = (np.asarray(violation) <= 0) & np.all(np.isfinite(f), axis=-1)
    if not np.any(ok):
        return 0.0
    with jax.enable_x64(True):
        return float(pareto.hypervolume(jnp.asarray(f[ok], jnp.float64),
                                        jnp.asarray(ref, jnp.float64)))


def nondominated(f: np.ndarray, violation: np.ndarray) -> np.ndarray:
    """The feasible non-dominated points of ``f`` ``(n, 2)``, sorted by the first objective."""
    ok = (np.asarray(violation) <= 0) & np.all(np.isfinite(f), axis=-1)
    pts = np.asarray(f, np.float64)[ok]
    keep = [i for i, p in enumerate(pts)
            if not np.any(np.all(pts <= p, axis=1) & np.any(pts < p, axis=1))]
    front = pts[keep]
    return front[np.argsort(front[:, 0], kind="stable")] if len(front) else front.reshape(0, 2)


def run_colony(problem, seeds: list[int], ants: int, generations: int) -> tuple[list, dict]:
    """MOEACO on all seeds at once (vmapped): each seed's final archive and the timing."""
    result = ea.minimize(problem, strategy=MOEACO(num_ants=ants, archive_size=ants),
                         seed=seeds, iterations=generations)
    finals = []
    for i in range(len(seeds)):
        s = (result.state if len(seeds) == 1  # one seed: minimize returns it unbatched
             else jax.tree.map(lambda a, i=i: a[i], result.state))
        finals.append({"x": np.asarray(s.archive_x), "f": np.asarray(s.archive_f, np.float64),
                       "violation": np.asarray(s.archive_v, np.float64)})
    timing = {"compile_s": result.compile_seconds,
              "run_s_all_seeds": result.seconds - result.compile_seconds,
              "evaluations": [int(e) for e in np.atleast_1d(np.asarray(result.evaluations))],
              "history_hypervolume": np.asarray(result.history["hypervolume"]).tolist(),
              "history_feasible": np.asarray(result.history["feasible"]).tolist()}
    return finals, timing


def seeds_evaluate(problem, rows: int):
    """``problem.evaluate`` jitted and vmapped over ``rows`` seeds, ``(rows, ants, dim)`` with
    one key per row (ignored by a problem without worlds), as NSGA-II's arm calls it; MuJoCo
    Warp's shared contact buffer sized for every row (``for_rows``)."""
    prob = problem.for_rows(rows) if hasattr(problem, "for_rows") else problem
    if problem.stochastic:
        return jax.jit(jax.vmap(prob.evaluate))
    return jax.jit(jax.vmap(lambda x, _k: prob.evaluate(x)))


def run_nsga2(problem, seeds: list[int], ants: int, generations: int) -> tuple[list, dict]:
    """pymoo's NSGA-II through its ask-and-tell API, all seeds in lockstep: each generation's
    populations of every seed are evaluated as one call, the jitted evaluation vmapped over the
    seeds with each seed's own optimisation-stream key (fresh each generation), as the
    colony's vmapped seeds are; so both arms pay the same batched physics."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.problems.static import StaticProblem

    evaluate = seeds_evaluate(problem, len(seeds))

    class GaitMO(Problem):
        def __init__(self) -> None:
            super().__init__(n_var=problem.dim, n_obj=2, n_ieq_constr=1,
                             xl=np.asarray(problem.lower, np.float64),
                             xu=np.asarray(problem.upper, np.float64))

    mo = GaitMO()
    mid = (np.asarray(problem.lower, np.float64) + np.asarray(problem.upper, np.float64)) / 2
    algos = []
    for s in seeds:
        algo = NSGA2(pop_size=ants)
        algo.setup(mo, termination=("n_eval", ants * generations), seed=s, verbose=False)
        algos.append(algo)
    calls = [0] * len(seeds)
    t0 = time.perf_counter()
    warm = jnp.broadcast_to(jnp.asarray(mid, problem.dtype), (len(seeds), ants, problem.dim))
    jax.block_until_ready(evaluate(warm, jax.vmap(jax.random.PRNGKey)(jnp.asarray(seeds))))
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    while any(a.has_next() for a in algos):
        live = [i for i, a in enumerate(algos) if a.has_next()]
        pops = {i: algos[i].ask() for i in live}
        xs = {i: np.asarray(pops[i].get("X"), np.float64) for i in live}
        rounds = max(-(-len(x) // ants) for x in xs.values())
        fs = {i: [] for i in live}
        vs = {i: [] for i in live}
        for r in range(rounds):  # each round: every live seed's next (padded) chunk of ants
            batch, keys = [], []
            for i, s in enumerate(seeds):
                x = xs.get(i, mid[None])[r * ants:(r + 1) * ants]  # done seeds: the mid-box
                x = x if len(x) else mid[None]
                batch.append(np.concatenate([x, np.repeat(x[:1], ants - len(x), axis=0)]))
                keys.append(jax.random.fold_in(jax.random.PRNGKey(s), calls[i]))
                calls[i] += i in xs
            e = evaluate(jnp.asarray(np.stack(batch), problem.dtype), jnp.stack(keys))
            f, v = np.asarray(e.f, np.float64), np.asarray(e.violation, np.float64)
            for i in live:
                n = min(ants, len(xs[i]) - r * ants)
                if n > 0:
                    fs[i].append(f[i, :n])
                    vs[i].append(v[i, :n])
        for i in live:
            static = StaticProblem(mo, F=np.concatenate(fs[i]), G=np.concatenate(vs[i])[:, None])
            algos[i].evaluator.eval(static, pops[i])  # counts toward its n_eval
            algos[i].tell(infills=pops[i])
    seconds = time.perf_counter() - t0
    finals, counts = [], []
    for algo in algos:
        pop = algo.result().pop
        counts.append(int(algo.evaluator.n_eval))
        finals.append({"x": np.asarray(pop.get("X"), np.float32),
                       "f": np.asarray(pop.get("F"), np.float64),
                       "violation": np.maximum(np.asarray(pop.get("G"), np.float64)[:, 0], 0)})
    return finals, {"compile_s": compile_s, "run_s_all_seeds": seconds, "evaluations": counts,
                    "batched_calls": calls}


def natural(f: np.ndarray, second: str) -> np.ndarray:
    """Objectives ``(n, 2)`` as the user reads them: speed (m/s) and endurance (min) / CoT."""
    f = np.asarray(f, np.float64).reshape(-1, 2)
    return np.stack([-f[:, 0], -f[:, 1] if second == "endurance" else f[:, 1]], axis=1)


def plot(rows: dict, second: str, seed: int, path: Path, title: str) -> None:
    """Left: seed ``seed``'s rescored fronts of both arms (its infeasible final points faint,
    with the least violation's annotated); right: the union over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    ylabel = ("endurance until the firmware limit (min, capped)" if second == "endurance"
              else "electrical cost of transport")
    for arm, colour in (("colony", "tab:red"), ("nsga2", "tab:blue")):
        seeds = rows[arm]["seeds"]
        one = next(s for s in seeds if s["seed"] == seed)
        union = np.concatenate([np.asarray(s["rescored_front"]).reshape(-1, 2) for s in seeds])
        for ax, pts, what in ((axes[0], np.asarray(one["rescored_front"]).reshape(-1, 2),
                               f"seed {seed}"), (axes[1], nondominated(
                                   union, np.zeros(len(union))), "union of seeds")):
            nat = natural(pts, second)
            ax.step(nat[:, 0], nat[:, 1], where="post", c=colour, lw=1, alpha=0.6)
            ax.scatter(nat[:, 0], nat[:, 1], s=14, c=colour,
                       label=f"{LABEL[arm]} ({what}, {len(nat)} feasible)")
        every = np.asarray(one["rescored_all"]).reshape(-1, 3)
        bad = every[every[:, 2] > 0]
        if len(bad):
            nat = natural(bad[:, :2], second)
            axes[0].scatter(nat[:, 0], nat[:, 1], s=10, marker="x", c=colour, alpha=0.3,
                            label=f"{LABEL[arm]} infeasible (least violation "
                                  f"{bad[:, 2].min():.2f})")
    for ax, sub in zip(axes, (f"seed {seed}", "union over seeds"), strict=True):
        ax.set_xlabel("speed (m/s, aggregated over the worlds)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{sub}: feasible fronts in the selection worlds", fontsize=9)
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--second", choices=("endurance", "cot"), default="endurance")
    ap.add_argument("--backend", default="auto", choices=("auto", "native", "mjx"))
    ap.add_argument("--impl", default="auto", choices=("auto", "jax", "warp"))
    ap.add_argument("--horizon", type=float, default=20.0)
    ap.add_argument("--worlds", type=int, default=8, help="R randomised worlds per evaluation")
    ap.add_argument("--worlds-seed", type=int, default=0,
                    help="seed of the three world streams (both arms, every run seed)")
    ap.add_argument("--fixed-worlds", action="store_true",
                    help="every evaluation in the optimisation stream's batch 0")
    ap.add_argument("--score-worlds", type=int, default=None,
                    help="selection-stream worlds the final fronts are rescored in "
                         "(default: --worlds)")
    ap.add_argument("--ants", type=int, default=128, help="ants = archive = NSGA-II population")
    ap.add_argument("--generations", type=int, default=20)
    ap.add_argument("--seeds", default="0-9", help="run seeds (both arms, paired)")
    ap.add_argument("--init", type=Path, default=None,
                    help="both arms search +/-15%% of each range around this stored gait "
                         "(eaco gait --init's box)")
    ap.add_argument("--steer", action="store_true",
                    help="close the heading loop (eaco_jax.gait.steer defaults), as gait --steer")
    ap.add_argument("--target-noise", type=float, default=None,
                    help="joint-target noise std of the worlds, rad (default: the ranges')")
    ap.add_argument("--smoke", action="store_true",
                    help="label the record a smoke run (a harness check, no claims)")
    ap.add_argument("--out", type=Path, default=None, help="default results/gait_fronts/<tag>")
    args = ap.parse_args(argv)
    import pymoo

    seeds = parse_seeds(args.seeds)
    score_n = args.score_worlds or args.worlds
    robust = world_ranges(args.worlds_seed, args.target_noise, R=args.worlds,
                          resample=not args.fixed_worlds)
    problem = make_gait_mo_problem("nao", args.second, backend=args.backend, impl=args.impl,
                                   horizon=args.horizon, robust=robust,
                                   steering=steering_of(args.steer))
    if args.init is not None:  # the same narrowed box for both arms
        problem, _ = narrowed_around(problem, args.init)
    tag = (f"{'smoke_' if args.smoke else ''}{args.second}_{'steer_' if args.steer else ''}"
           f"{problem.backend}_"
           f"{args.horizon:g}s_{args.ants}x{args.worlds}_g{args.generations}")
    out = args.out or RESULTS / f"{tag}.json"
    ref = np.asarray(problem.ref_point, np.float64)
    sel = problem.worlds(stream_key(args.worlds_seed, "selection"), score_n)
    rescore = jax.jit(problem.evaluate_in)

    rows: dict = {}
    for arm, runner in (("colony", run_colony), ("nsga2", run_nsga2)):
        t0 = time.perf_counter()
        finals, timing = runner(problem, seeds, args.ants, args.generations)
        timing["wall_s"] = time.perf_counter() - t0
        per_seed = []
        for s, fin in zip(seeds, finals, strict=True):
            e = rescore(jnp.asarray(fin["x"], problem.dtype), sel)
            fr, vr = np.asarray(e.f, np.float64), np.asarray(e.violation, np.float64)
            per_seed.append({
                "seed": s,
                "search_hypervolume": hypervolume(fin["f"], fin["violation"], ref),
                "search_feasible": int(np.sum(fin["violation"] <= 0)),
                "search_min_violation": float(np.min(fin["violation"])),
                "rescored_hypervolume": hypervolume(fr, vr, ref),
                "rescored_feasible": int(np.sum(vr <= 0)),
                "rescored_min_violation": float(np.min(vr)),
                "rescored_front": np.round(nondominated(fr, vr), 6).tolist(),
                "rescored_front_x": np.round(np.asarray(fin["x"], np.float64)[
                    _front_rows(fr, vr)], 6).tolist(),
                "rescored_all": np.round(np.column_stack([fr, vr]), 6).tolist(),
            })
        rows[arm] = {"seeds": per_seed, "timing": timing,
                     **{k: summarise([r[k] for r in per_seed])
                        for k in ("search_hypervolume", "rescored_hypervolume",
                                  "rescored_feasible", "rescored_min_violation")}}
        print(f"{arm}: rescored HV {rows[arm]['rescored_hypervolume']['mean']:.4f} "
              f"[{rows[arm]['rescored_hypervolume']['ci_low']:.4f}, "
              f"{rows[arm]['rescored_hypervolume']['ci_high']:.4f}], search HV "
              f"{rows[arm]['search_hypervolume']['mean']:.4f}, wall {timing['wall_s']:.1f} s",
              flush=True)
    comparison = {}
    for k in ("search_hypervolume", "rescored_hypervolume", "rescored_min_violation"):
        a = [r[k] for r in rows["colony"]["seeds"]]
        b = [r[k] for r in rows["nsga2"]["seeds"]]
        d = np.asarray(a) - np.asarray(b)  # violation: lower is better
        comparison[k] = {"difference_colony_minus_nsga2": summarise(d.tolist()),
                         "wilcoxon_paired_p": st.paired_test(a, b),
                         "colony_better_seeds": int(np.sum(d > 0)),
                         "nsga2_better_seeds": int(np.sum(d < 0))}
    png = out.with_suffix(".png")
    title = (f"NAO speed x {args.second}, {problem.backend}, {args.horizon:g} s, "
             f"{args.ants} ants x {args.worlds} worlds x {args.generations} generations"
             + (" (SMOKE RUN: harness check only)" if args.smoke else ""))
    plot(rows, args.second, seeds[0], png, title)
    table = [{"arm": arm, "rescored_hv_mean": rows[arm]["rescored_hypervolume"]["mean"],
              "rescored_hv_ci": [rows[arm]["rescored_hypervolume"]["ci_low"],
                                 rows[arm]["rescored_hypervolume"]["ci_high"]],
              "search_hv_mean": rows[arm]["search_hypervolume"]["mean"]} for arm in ARMS]
    st.write_results(
        out, table, arms=rows, comparison=comparison,
        smoke_run=bool(args.smoke),
        note=("SMOKE RUN: a tiny CPU budget that proves the harness end to end; no claims are "
              "made from it") if args.smoke else None,
        problem={"name": problem.name, "second": args.second,
                 "objectives": list(problem.objective_names),
                 "constraints": list(problem.constraint_names),
                 "ref_point": ref.tolist(), "backend": problem.backend, "impl": problem.impl,
                 "horizon_s": args.horizon, "worlds": args.worlds,
                 "aggregate": robust.aggregate, "resample": robust.resample,
                 "target_noise": robust.target_noise,
                 "init": None if args.init is None else str(args.init),
                 "steering": None if problem.steering is None else problem.steering.record()},
        budget={"ants": args.ants, "generations": args.generations,
                "evaluations_per_seed": args.ants * args.generations,
                "rollouts_per_seed": args.ants * args.generations * args.worlds},
        seeds={"run_seeds": seeds, "worlds_seed": args.worlds_seed,
               "optimisation": "optimisation stream of worlds_seed, a batch per generation",
               "scoring": f"selection stream of worlds_seed, batch 0, {score_n} worlds",
               "tuning": "none on this problem: MOEACO's MOParams defaults (chosen on ZDT1 / "
                         "DTLZ2 seeds 0-9), NSGA-II pymoo defaults"},
        provenance={"date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                    "command": "python experiments/gait_fronts.py " + " ".join(
                        sys.argv[1:] if argv is None else argv),
                    "versions": {"jax": jax.__version__, "eaco_jax": ea.__version__,
                                 "pymoo": pymoo.__version__}},
        figure=str(png.relative_to(st.REPO)) if png.is_relative_to(st.REPO) else str(png))
    print(f"wrote {out} and {png}")
    return out


def _front_rows(f: np.ndarray, violation: np.ndarray) -> np.ndarray:
    """Indices of the feasible non-dominated rows of ``f``, sorted by the first objective."""
    ok = np.flatnonzero((violation <= 0) & np.all(np.isfinite(f), axis=-1))
    pts = f[ok]
    keep = [i for i, p in zip(ok, pts, strict=True)
            if not np.any(np.all(pts <= p, axis=1) & np.any(pts < p, axis=1))]
    return np.asarray(sorted(keep, key=lambda i: (f[i, 0], i)), np.int64)


if __name__ == "__main__":
    main()
