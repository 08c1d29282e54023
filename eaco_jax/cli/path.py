"""``eaco path``: plan a collision-free walk among polygonal obstacles (paper §5)."""

from __future__ import annotations

from pathlib import Path

import typer

from eaco_jax.cli.common import emit_json, guarded, register_runner, write_json


def run_path(
    obstacles: int = 10,
    world_seed: int = 1,
    ants: int = 32,
    iterations: int = 150,
    seed: int = 0,
    json: bool = False,
    quiet: bool = False,
    out: str | None = None,
    checkpoint_dir: str | None = None,
    checkpoint_every: int | None = None,
) -> dict:
    """Solve one random obstacle world; returns the JSON record."""
    import numpy as np

    import eaco_jax as ea
    from eaco_jax.problems.path_planning import random_environment
    from eaco_jax.strategies.path_eaco import PathEACO

    args = {k: v for k, v in locals().items() if k not in {"np", "ea", "random_environment",
                                                           "PathEACO"}}
    radius = (0.06, 0.12) if obstacles <= 12 else (0.03, 0.06)
    problem = random_environment(obstacles, seed=world_seed, radius=radius)
    extra = {}
    if checkpoint_dir is not None:
        extra = dict(checkpoint_dir=checkpoint_dir, checkpoint_every=checkpoint_every,
                     run_info={"command": "path", "args": args})
    result = ea.minimize(problem, PathEACO(num_ants=ants), seed=seed, iterations=iterations,
                         progress=not (json or quiet), **extra)
    best = np.asarray(result.best_solution)
    waypoints = problem.waypoints(best)
    length = float(result.best_cost)
    record = {
        "problem": problem.name,
        "obstacles": obstacles,
        "nodes": problem.n,
        "length": length,
        "optimum": problem.optimum,
        "gap_percent": 100.0 * (length / problem.optimum - 1.0),
        "waypoints": waypoints.tolist(),
        "iterations": result.iterations,
        "evaluations": int(result.evaluations),
        "seconds": result.seconds,
        "seconds_per_iteration": result.seconds_per_iteration,
        "history_best": result.history["best_cost"].tolist(),
    }
    if out is not None:
        from eaco_jax import plots

        folder = Path(out)
        write_json(folder / "result.json", record)
        plots.convergence(result.history, folder / "convergence.png", optimum=problem.optimum,
                          title=f"EACO path planning, {problem.name}", ylabel="path length")
        plots.planned_path(problem.obstacles, waypoints, folder / "path.png",
                           title=f"{problem.name}: length {length:.3f} "
                                 f"(optimum {problem.optimum:.3f})")
        record["out"] = str(folder)
    return record


register_runner("path", run_path)


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def path(
        obstacles: int = typer.Option(10, help="Number of convex obstacles."),
        world_seed: int = typer.Option(1, help="Seed of the random obstacle world."),
        ants: int = typer.Option(32, help="Ants per iteration."),
        iterations: int = typer.Option(150, help="Colony iterations."),
        seed: int = typer.Option(0, help="Seed of the colony."),
        out: str | None = typer.Option(None, help="Folder for result.json and plots."),
        json: bool = typer.Option(False, "--json", help="Print one JSON line, no progress bar."),
        quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
        checkpoint_dir: str | None = typer.Option(None, help="Checkpoint (and resume) here."),
        checkpoint_every: int | None = typer.Option(None, help="Iterations between saves."),
    ) -> None:
        """Plan the shortest collision-free path from start to goal among obstacles."""
        record = run_path(obstacles=obstacles, world_seed=world_seed, ants=ants,
                          iterations=iterations, seed=seed, json=json, quiet=quiet, out=out,
                          checkpoint_dir=checkpoint_dir, checkpoint_every=checkpoint_every)
        if json:
            emit_json(record)
        else:
            typer.echo(f"{record['problem']}: path length {record['length']:.4f} "
                       f"(optimum {record['optimum']:.4f}, gap {record['gap_percent']:.2f}%)")
