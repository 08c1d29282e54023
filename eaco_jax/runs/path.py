"""The ``path`` run: plan a collision-free walk among polygonal obstacles (paper section 5).

Outputs in ``out``: ``result.json``, ``convergence.png`` and ``path.png``.
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
    check_out,
    check_settings,
    entered,
    params_from,
    setting,
)
from eaco_jax.runs.tsp import PARAMS_HELP


@dataclasses.dataclass(frozen=True)
class PathSettings:
    obstacles: int = setting(10, "number of convex obstacles")
    world_seed: int = setting(1, "seed of the random obstacle world")
    ants: int = setting(32, "ants per iteration")
    iterations: int = setting(150, "colony iterations")
    seed: int = setting(0, "seed of the colony")
    max_evaluations: int | None = setting(None, "evaluation budget (a hard cap; replaces "
                                          "--iterations)")
    max_seconds: float | None = setting(None, "stop after this many compute seconds")
    params: str | None = setting(None, PARAMS_HELP)
    out: str | None = setting(None, "folder for result.json and plots")

    def __post_init__(self) -> None:
        check_settings(self, "obstacles", "ants", "iterations", "max_evaluations")


def build(s: PathSettings) -> Built:
    from eaco_jax.problems.path_planning import random_environment
    from eaco_jax.strategies.path_eaco import PathEACO

    radius = (0.06, 0.12) if s.obstacles <= 12 else (0.03, 0.06)
    problem = random_environment(int(s.obstacles), seed=int(s.world_seed), radius=radius)
    strategy = PathEACO(num_ants=int(s.ants))
    params = params_from(strategy, problem, s.params)
    return Built(problem, strategy, params, budget_of(s, s.iterations))


def row_metrics(built: Built, result: Any, row: int) -> dict[str, Any]:
    length = float(np.asarray(result.best_cost).reshape(-1)[row])
    return {"gap_percent": 100.0 * (length / built.problem.optimum - 1.0)}


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
    length = float(result.best_cost)
    record: dict[str, Any] = {
        "problem": problem.name,
        "obstacles": int(s.obstacles),
        "nodes": problem.n,
        "length": length,
        "optimum": problem.optimum,
        "gap_percent": 100.0 * (length / problem.optimum - 1.0),
        "waypoints": waypoints.tolist(),
        "iterations": result.iterations,
        "evaluations": int(result.evaluations),
        "stop_reason": result.stop_reason,
        "seconds": result.seconds,
        "seconds_per_iteration": result.seconds_per_iteration,
        "history_best": result.history["best_cost"].tolist(),
    }
    if s.out is not None:
        from eaco_jax import plots
        from eaco_jax.outputs import write_json

        folder = Path(s.out)
        record["out"] = str(folder)
        write_json(folder / "result.json", record)
        plots.convergence(result.history, folder / "convergence.png", optimum=problem.optimum,
                          title=f"EACO path planning, {problem.name}", ylabel="path length")
        plots.planned_path(problem.obstacles, waypoints, folder / "path.png",
                           title=f"{problem.name}: length {length:.3f} "
                                 f"(optimum {problem.optimum:.3f})")
    return record


def summary(record: dict[str, Any]) -> str:
    return (f"{record['problem']}: path length {record['length']:.4f} "
            f"(optimum {record['optimum']:.4f}, gap {record['gap_percent']:.2f}%)")


KIND = RunKind("path", PathSettings, build, run, row_metrics, summary)
