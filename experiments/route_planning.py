"""Least-walking-time routes through random ten-obstacle scenes: the path colony and the path
GA against the exact time-optimal route (issue 32; the paper's Figs. 4-7).

    python experiments/route_planning.py                  # full run, a few minutes on 2 cores
    python experiments/route_planning.py --quick          # 4 scenes x 2 seeds, a smoke test

Seeds and scenes are kept apart:

* selection scenes ``random_scene(0..24)``: the GA's rates are chosen here (a grid over
  crossover and mutation rate, Fig. 4); the colony runs its defaults (nothing chosen);
* report scenes ``random_scene(100..124)``: every reported gap; optimisation seeds 0..S-1 of
  each strategy (the searchers' PRNG), the same for both.

Both searchers get the same evaluations (``ants x iterations``). The gap of a run is
``time / optimum - 1`` where the optimum is :func:`eaco_jax.problems.scenes.time_optimal_route`
on the same visibility graph. One compiled program per strategy runs every scene and seed
(problems padded to one node count, vmapped).

Outputs in ``experiments/results/route_planning/``: ``route_planning.json`` (rows, CIs,
provenance), ``fig4_ga_rates.png`` and ``fig5..7_routes_scene<k>.png``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import common
import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from eaco_jax.problems.scenes import build_problem, random_scene  # noqa: E402
from eaco_jax.strategies import get  # noqa: E402
from eaco_jax.strategies.path_ga import PathGAParams  # noqa: E402

OUT = common.REPO / "experiments" / "results" / "route_planning"


def problems(scenes: list[int]) -> tuple[list, object]:
    """The scenes' problems and one stacked copy (padded to a common node count)."""
    built = [build_problem(random_scene(s)) for s in scenes]
    n = max(p.n for p in built)
    padded = [dataclasses.replace(build_problem(random_scene(s), pad_to=n), scene=None,
                                  name="scene", optimum=None, optimal_route=()) for s in scenes]
    return built, jax.tree.map(lambda *x: jnp.stack(x), *padded)


def run_all(strategy, stacked, params, seeds: list[int], iterations: int) -> np.ndarray:
    """Best cost after ``iterations`` for every (setting, scene, seed): (P, S, R) array.
    ``params`` is a Params pytree with a leading settings axis."""

    def one(problem, p, seed):
        key = jax.random.key(seed)
        k_init, k_run = jax.random.split(key)
        state = strategy.init(k_init, problem, p)

        def step(state, k):
            sols, state = strategy.ask(k, state, problem)
            state, _ = strategy.tell(state, sols, problem.evaluate(sols), problem)
            return state, None

        state, _ = jax.lax.scan(step, state, jax.random.split(k_run, iterations))
        return state.best_cost

    f = jax.vmap(one, in_axes=(None, None, 0))  # seeds
    f = jax.vmap(f, in_axes=(0, None, None))  # scenes
    f = jax.vmap(f, in_axes=(None, 0, None))  # settings
    return np.asarray(jax.jit(f)(stacked, params, jnp.asarray(seeds)))


def stacked_params(strategy, **grid: list[float]):
    base = strategy.default_params(None)
    size = len(next(iter(grid.values())))
    leaves = {k: jnp.broadcast_to(jnp.asarray(getattr(base, k)), (size,)) for k in
              [f.name for f in dataclasses.fields(base)]}
    leaves.update({k: jnp.asarray(v, jnp.float32) for k, v in grid.items()})
    return type(base)(**leaves)


def gaps(costs: np.ndarray, built: list) -> np.ndarray:
    opt = np.array([p.optimum for p in built])[None, :, None]
    return 100.0 * (costs / opt - 1.0)


def draw_routes(problem, routes: dict[str, np.ndarray], path: Path, title: str) -> None:
    from matplotlib.patches import Polygon

    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for r in problem.scene.ramps:
        ax.add_patch(Polygon(np.asarray(r.polygon), closed=True, facecolor="tan", alpha=0.5,
                             hatch="//", edgecolor="0.4"))
    for o in problem.scene.obstacles:
        ax.add_patch(Polygon(np.asarray(o.polygon), closed=True, color="0.55", alpha=0.8))
    styles = {"optimum": ("--", "tab:green"), "EACO": ("-o", "tab:blue"), "GA": ("-s", "tab:red")}
    for label, sol in routes.items():
        w = problem.waypoints(sol)
        t = float(problem.evaluate(jnp.asarray(sol)[None])[0])
        ls, c = styles[label]
        ax.plot(w[:, 0], w[:, 1], ls, color=c, ms=3, lw=1.6, label=f"{label}: {t:.2f} s")
    ax.plot(*problem.scene.start, "ks", ms=8)
    ax.plot(*problem.scene.goal, "*", color="tab:red", ms=12)
    ax.set_aspect("equal")
    ax.set_xlim(problem.scene.bounds[0], problem.scene.bounds[2])
    ax.set_ylim(problem.scene.bounds[1], problem.scene.bounds[3])
    ax.set_title(title, fontsize=9)
    ax.legend(loc="lower right", fontsize=8)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def best_routes(strategy, problem, params, seed: int, iterations: int) -> np.ndarray:
    state = strategy.init(jax.random.key(seed), problem, params)
    key = jax.random.key(seed + 1)
    for _ in range(iterations):
        key, k = jax.random.split(key)
        sols, state = strategy.ask(k, state, problem)
        state, _ = strategy.tell(state, sols, problem.evaluate(sols), problem)
    return np.asarray(state.best_solution)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ants", type=int, default=32)
    ap.add_argument("--iterations", type=int, default=100)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--scenes", type=int, default=25)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    if args.quick:
        args.scenes, args.seeds, args.iterations = 4, 2, 30
    OUT.mkdir(parents=True, exist_ok=True)
    select = list(range(args.scenes))
    report = list(range(100, 100 + args.scenes))
    seeds = list(range(args.seeds))
    t0 = time.time()
    colony, ga = get("path-eaco", num_ants=args.ants), get("path-ga", num_ants=args.ants)

    # Fig. 4 and the GA's rates: chosen on the selection scenes
    sel_built, sel = problems(select)
    crossover = [0.0, 0.25, 0.5, 0.75, 1.0]
    mutation = [0.0, 0.25, 0.5, 0.75, 1.0]
    grid = [(c, m) for c in crossover for m in mutation]
    ga_grid = run_all(ga, sel, stacked_params(ga, p_crossover=[c for c, _ in grid],
                                              p_mutation=[m for _, m in grid]),
                      seeds[:1], args.iterations)
    grid_gap = gaps(ga_grid, sel_built).mean(axis=(1, 2))  # (settings,)
    chosen = grid[int(np.argmin(grid_gap))]
    table = grid_gap.reshape(len(crossover), len(mutation))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6))
    for j, m in enumerate(mutation):
        a1.plot(crossover, table[:, j], "-o", ms=3, label=f"mutation {m:g}")
    for i, c in enumerate(crossover):
        a2.plot(mutation, table[i], "-o", ms=3, label=f"crossover {c:g}")
    a1.set_xlabel("crossover rate")
    a2.set_xlabel("mutation rate")
    for a in (a1, a2):
        a.set_ylabel("GA mean gap to the time optimum [%]")
        a.legend(fontsize=6)
    fig.suptitle(f"Fig. 4 counterpart: GA route time vs rates, selection scenes 0-"
                 f"{select[-1]}, seed 0, {args.ants} x {args.iterations} evaluations",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT / "fig4_ga_rates.png", dpi=110)
    plt.close(fig)

    # reported: both searchers at equal evaluations on the report scenes
    rep_built, rep = problems(report)
    col = gaps(run_all(colony, rep, stacked_params(colony, q0=[0.2]), seeds, args.iterations),
               rep_built)[0]
    gap_ga = gaps(run_all(ga, rep, stacked_params(ga, p_crossover=[chosen[0]],
                                                  p_mutation=[chosen[1]]),
                          seeds, args.iterations), rep_built)[0]
    rows = []
    for name, g in (("path-eaco", col), ("path-ga", gap_ga)):
        per_scene = g.mean(axis=1)
        lo, hi = common.bootstrap_ci(per_scene.tolist())
        rows.append({
            "strategy": name, "mean_gap_percent": float(g.mean()), "ci95_percent": [lo, hi],
            "median_gap_percent": float(np.median(g)), "max_gap_percent": float(g.max()),
            "runs_within_1_percent": int((g <= 1.0).sum()), "runs": int(g.size),
            "optimum_hits": int((g <= 1e-3).sum()), "per_scene_mean": per_scene.tolist()})
    p_value = common.paired_test(col.mean(axis=1).tolist(), gap_ga.mean(axis=1).tolist())

    # Figs. 5-7: both routes on three report scenes
    ga_params = PathGAParams(p_crossover=jnp.float32(chosen[0]),
                             p_mutation=jnp.float32(chosen[1]))
    for fig_no, k in zip((5, 6, 7), range(3), strict=True):
        p = rep_built[k]
        routes = {"optimum": p.route(list(p.optimal_route)),
                  "EACO": best_routes(colony, p, None, 0, args.iterations),
                  "GA": best_routes(ga, p, ga_params, 0, args.iterations)}
        draw_routes(p, routes, OUT / f"fig{fig_no}_routes_scene{report[k]}.png",
                    f"Fig. {fig_no}: scene {report[k]}, seed 0, {args.ants} x {args.iterations} "
                    "evaluations each")

    common.write_results(
        OUT / "route_planning.json", rows,
        what="mean gap [%] of the best route's walking time to the exact time-optimal route "
             "(Dijkstra over directed-edge states on the scene's visibility graph)",
        select_scenes=f"random_scene({select[0]}..{select[-1]})",
        report_scenes=f"random_scene({report[0]}..{report[-1]})",
        optimisation_seeds=seeds, fig4_seeds=seeds[:1],
        evaluations_per_run=args.ants * args.iterations, ants=args.ants,
        iterations=args.iterations, ga_chosen={"p_crossover": chosen[0], "p_mutation": chosen[1]},
        colony_params="PathEACO defaults (nothing chosen)",
        fig4_grid={"crossover": crossover, "mutation": mutation, "mean_gap_percent":
                   table.tolist()},
        wilcoxon_p_colony_vs_ga=p_value, seconds=time.time() - t0,
        ci="95% bootstrap CI of the mean over report scenes (each scene's mean over seeds)")
    for r in rows:
        print(f"{r['strategy']}: mean gap {r['mean_gap_percent']:.3f}% "
              f"CI {r['ci95_percent'][0]:.3f}..{r['ci95_percent'][1]:.3f}%, "
              f"{r['runs_within_1_percent']}/{r['runs']} runs within 1%")
    print(f"GA chosen {chosen}; p = {p_value:.3g}; {time.time() - t0:.0f} s -> {OUT}")


if __name__ == "__main__":
    main()
