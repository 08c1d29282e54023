"""``eaco tsp FILE_OR_NAME``: solve a TSPLIB instance with the graph EACO colony.

``FILE_OR_NAME`` is a bundled instance name (``eil51``) or a path to a ``.tsp`` file. With
``--json`` the last stdout line is one JSON record; ``--out DIR`` also writes ``result.json``,
``history.csv``, ``convergence.png`` and ``tour.png``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from eaco_jax.cli.common import emit_json, guarded, register_runner, write_json

DEFAULT_ITERATIONS = 300


def run_tsp(
    instance: str,
    ants: int = 40,
    iterations: int = DEFAULT_ITERATIONS,
    seed: int = 0,
    local_search: bool = True,
    json: bool = False,
    out: str | None = None,
    checkpoint_dir: str | None = None,
    checkpoint_every: int | None = None,
    quiet: bool = False,
) -> dict[str, Any]:
    """Solve ``instance`` and return the JSON record; writes ``out`` if given."""
    from eaco_jax.driver.minimize import minimize
    from eaco_jax.problems.tsp import load_tsplib, tour_length
    from eaco_jax.strategies.graph_eaco import GraphEACO

    if ants < 1:
        raise ValueError(f"--ants must be >= 1, got {ants}")
    if iterations < 1:
        raise ValueError(f"--iterations must be >= 1, got {iterations}")
    args = dict(instance=str(instance), ants=ants, iterations=iterations, seed=seed,
                local_search=local_search, json=json, out=out,
                checkpoint_every=checkpoint_every, quiet=quiet)
    problem = load_tsplib(instance)
    strategy = GraphEACO(num_ants=int(ants), local_search="2opt" if local_search else "none")
    kwargs: dict[str, Any] = {}
    if checkpoint_dir is not None:
        kwargs.update(checkpoint_dir=checkpoint_dir, checkpoint_every=checkpoint_every,
                      run_info={"command": "tsp", "args": args})
    result = minimize(problem, strategy, seed=int(seed), iterations=int(iterations),
                      progress=not (json or quiet), **kwargs)
    tour = np.asarray(result.best_solution, dtype=np.int64)
    length = int(tour_length(np.asarray(problem.dist), tour))
    record: dict[str, Any] = {
        "instance": problem.name,
        "n": int(problem.n),
        "ants": int(ants),
        "seed": int(seed),
        "local_search": bool(local_search),
        "best_length": length,
        "optimum": problem.optimum,
        "tour": tour.tolist(),
        "iterations": int(result.iterations),
        "evaluations": int(np.asarray(result.evaluations)),
        "seconds": float(result.seconds),
        "compile_seconds": float(result.compile_seconds),
        "seconds_per_iteration": float(result.seconds_per_iteration),
        "history_best": np.asarray(result.history["best_cost"]).astype(np.int64).tolist(),
    }
    if problem.optimum is not None:
        record["gap_percent"] = 100.0 * (length / float(problem.optimum) - 1.0)
    if out is not None:
        write_outputs(Path(out), record, result.history, instance)
    return record


def instance_coords(instance: str) -> np.ndarray | None:
    """City coordinates of a bundled name or ``.tsp`` path (None for EXPLICIT matrices)."""
    from eaco_jax.problems.tsp import DATA_DIR
    from eaco_jax.problems.tsplib import read_tsplib

    text = str(instance)
    bare = "/" not in text and "\\" not in text and not text.endswith(".tsp")
    path = DATA_DIR / f"{text}.tsp" if bare else Path(text)
    return read_tsplib(path).coords


def write_outputs(folder: Path, record: dict[str, Any], history: dict[str, np.ndarray],
                  instance: str) -> None:
    """``result.json``, ``history.csv``, ``convergence.png`` and ``tour.png`` in ``folder``."""
    from eaco_jax import plots

    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / "result.json", record)
    keys = list(history)
    with open(folder / "history.csv", "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["iteration", *keys])
        for i in range(len(np.asarray(history[keys[0]]))):
            writer.writerow([i + 1, *(np.asarray(history[k])[i].item() for k in keys)])
    plots.convergence(history, folder / "convergence.png", optimum=record.get("optimum"),
                      title=f"{record['instance']}: tour length", ylabel="tour length")
    coords = instance_coords(instance)
    if coords is not None:
        plots.tour(coords, np.asarray(record["tour"]), folder / "tour.png",
                   title=f"{record['instance']}: length {record['best_length']}")


register_runner("tsp", run_tsp)


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def tsp(
        instance: Annotated[str, typer.Argument(metavar="FILE_OR_NAME",
                                                help="a .tsp file or a bundled name (eil51)")],
        ants: Annotated[int, typer.Option(help="colony size")] = 40,
        iterations: Annotated[int, typer.Option(help="iterations")] = DEFAULT_ITERATIONS,
        seed: Annotated[int, typer.Option(help="random seed")] = 0,
        local_search: Annotated[bool, typer.Option(
            "--local-search/--no-local-search", help="2-opt on every tour")] = True,
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        out: Annotated[Path | None, typer.Option(help="folder for result.json, csv, plots")] = (
            None),
        checkpoint_dir: Annotated[Path | None, typer.Option(help="checkpoint folder")] = None,
        checkpoint_every: Annotated[int | None, typer.Option(
            help="iterations between checkpoints")] = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
    ) -> None:
        """Solve a TSPLIB instance with the EACO colony (MMAS-style defaults, 2-opt)."""
        record = run_tsp(
            instance, ants=ants, iterations=iterations, seed=seed, local_search=local_search,
            json=json_out, out=None if out is None else str(out),
            checkpoint_dir=None if checkpoint_dir is None else str(checkpoint_dir),
            checkpoint_every=checkpoint_every, quiet=quiet,
        )
        if json_out:
            emit_json(record)
        else:
            gap = record.get("gap_percent")
            typer.echo(
                f"{record['instance']}: best length {record['best_length']}"
                + (f" (optimum {record['optimum']:g}, gap {gap:.2f}%)" if gap is not None else "")
                + f" in {record['iterations']} iterations, {record['seconds']:.1f} s"
            )
