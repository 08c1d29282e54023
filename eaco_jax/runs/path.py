"""The ``path`` run: plan a collision-free walk among polygonal obstacles (paper section 5).

Without ``--scene`` it plans the shortest route through a random obstacle world (cost: length
[m]); with ``--scene FILE`` (or ``default``, ``random:SEED``) the least walking time [s]
through that scene (:mod:`eaco_jax.problems.scenes`). ``--strategy`` picks the path colony or
the path GA. Outputs in ``out``: ``result.json``, ``convergence.png`` and ``path.png``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.runs.base import (
    Built,
    RunKind,
    budget_of,
    check_choices,
    check_out,
    check_settings,
    entered,
    params_from,
    setting,
)
from eaco_jax.runs.tsp import PARAMS_HELP

#: the iteration budget of a run given neither --iterations, --max-evaluations nor --max-seconds
ITERATIONS = 150


@dataclasses.dataclass(frozen=True)
class PathSettings:
    scene: str | None = setting(None, "scene JSON file, 'default' or 'random:SEED': plan the "
                                "least walking time through it (else the shortest route "
                                "through a random world of --obstacles)")
    strategy: str = setting("path-eaco", "searcher", choices=("path-eaco", "path-ga"))
    obstacles: int = setting(10, "number of convex obstacles")
    world_seed: int = setting(1, "seed of the random obstacle world")
    ants: int = setting(32, "ants per iteration")
    iterations: int | None = setting(None, f"colony iterations (default {ITERATIONS}; with "
                                     "--max-seconds alone, no cap: time ends the run)")
    seed: int = setting(0, "seed of the colony")
    max_evaluations: int | None = setting(None, "evaluation budget (a hard cap; replaces "
                                          "--iterations)")
    max_seconds: float | None = setting(None, "stop after this many compute seconds")
    params: str | None = setting(None, PARAMS_HELP)
    out: str | None = setting(None, "folder for result.json and plots")

    def __post_init__(self) -> None:
        check_settings(self, "obstacles", "ants", "iterations", "max_evaluations")
        check_choices(self)


def build(s: PathSettings) -> Built:
    from eaco_jax.problems.path_planning import random_environment
    from eaco_jax.strategies import get

    if s.scene is not None:
        from eaco_jax.problems.scenes import scene_problem

        problem = scene_problem(s.scene)
    else:
        radius = (0.06, 0.12) if s.obstacles <= 12 else (0.03, 0.06)
        problem = random_environment(int(s.obstacles), seed=int(s.world_seed), radius=radius)
    strategy = get(s.strategy, num_ants=int(s.ants))
    params = params_from(strategy, problem, s.params)
    return Built(problem, strategy, params,
                 budget_of(s, s.iterations, {"iterations": ITERATIONS}))


def row_metrics(built: Built, result: Any, row: int) -> dict[str, Any]:
    cost = float(np.asarray(result.best_cost).reshape(-1)[row])
    return {"gap_percent": 100.0 * (cost / built.problem.optimum - 1.0)}


def run(s: PathSettings, *, progress: bool = False, checkpointing: Any = None) -> dict[str, Any]:
    """Solve one random obstacle world; returns the JSON record and writes ``s.out`` if set."""
    from eaco_jax.driver.minimize import minimize

    check_out(s.out)
    built = build(s)
    problem = built.problem
    with entered(built):
        result = minimize(problem, built.strategy, seed=int(s.seed), progress=progress,
                          checkpointing=checkpointing, params=built.params, **built.budget)
    best = np.asarray(result.best_solution)
    waypoints = problem.waypoints(best)
    cost = float(result.best_cost)
    timed = s.scene is not None
    record: dict[str, Any] = {
        "problem": problem.name,
        "strategy": s.strategy,
        "cost": "time_s" if timed else "length_m",
        "obstacles": len(problem.scene.obstacles) if timed else int(s.obstacles),
        "nodes": problem.n,
        "length": float(np.sum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1))),
        "optimum": problem.optimum,
        "gap_percent": 100.0 * (cost / problem.optimum - 1.0),
        "waypoints": waypoints.tolist(),
        "iterations": result.iterations,
        "evaluations": int(result.evaluations),
        "stop_reason": result.stop_reason,
        "seconds": result.seconds,
        "seconds_per_iteration": result.seconds_per_iteration,
        "history_best": result.history["best_cost"].tolist(),
    }
    if timed:
        record["time_s"] = cost
        record["optimal_waypoints"] = np.asarray(problem.coords)[
            list(problem.optimal_route)].tolist()
    if s.out is not None:
        from eaco_jax import plots
        from eaco_jax.outputs import write_json

        folder = Path(s.out)
        record["out"] = str(folder)
        write_json(folder / "result.json", record)
        unit = "walking time [s]" if timed else "path length"
        plots.convergence(result.history, folder / "convergence.png", optimum=problem.optimum,
                          title=f"{s.strategy} path planning, {problem.name}", ylabel=unit)
        if timed:
            plots.planned_path([o.polygon for o in problem.scene.obstacles], waypoints,
                               folder / "path.png",
                               title=f"{problem.name}: {cost:.2f} s (optimum "
                                     f"{problem.optimum:.2f} s)",
                               optimal=np.asarray(record["optimal_waypoints"]),
                               ramps=[r.polygon for r in problem.scene.ramps])
        else:
            plots.planned_path(problem.obstacles, waypoints, folder / "path.png",
                               title=f"{problem.name}: length {cost:.3f} "
                                     f"(optimum {problem.optimum:.3f})")
    return record


def summary(record: dict[str, Any]) -> str:
    if record.get("cost") == "time_s":
        return (f"{record['problem']}: walking time {record['time_s']:.3f} s over "
                f"{record['length']:.2f} m (time-optimal {record['optimum']:.3f} s, gap "
                f"{record['gap_percent']:.2f}%)")
    return (f"{record['problem']}: path length {record['length']:.4f} "
            f"(optimum {record['optimum']:.4f}, gap {record['gap_percent']:.2f}%)")


KIND = RunKind("path", PathSettings, build, run, row_metrics, summary)
