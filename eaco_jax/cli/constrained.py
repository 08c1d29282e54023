"""``eaco constrained NAME``: solve a CEC2006 problem (or a test function) with continuous EACO.

Runs in 64-bit precision (:func:`eaco_jax.problems.constrained.float64`, scoped to the run):
the CEC2006 success rule f - f* <= 1e-4 is finer than float32's spacing at |f| ~ 7000 (g10).
The run stops after the chunk in which the target f* + 1e-4 is reached (or at the budget).
"""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from eaco_jax.cli.common import emit_json, guarded, register_runner, write_json

#: unconstrained test functions also accepted as NAME (default dimension 10)
FUNCTIONS = ("sphere", "rosenbrock", "rastrigin", "ackley")


def load_problem(name: str) -> Any:
    """A CEC2006 problem (g01-g13, G1-G4) or a test function by name; ProblemError if unknown."""
    from eaco_jax.problems import cec2006, functions
    from eaco_jax.problems.base import ProblemError

    if name.lower() in FUNCTIONS:
        return getattr(functions, name.lower())()
    try:
        return cec2006(name)
    except ProblemError as err:
        raise ProblemError(f"{err.args[0]}, or a test function ({', '.join(FUNCTIONS)})") from None


def evaluations_to_target(state: Any) -> int | None:
    """First evaluation count with a feasible f - f* <= 1e-4, or None."""
    value = int(np.asarray(state.target_evaluations))
    return value if value >= 0 else None


def run_constrained(
    problem: str,
    method: str = "epsilon",
    seed: int = 0,
    max_evaluations: int = 500_000,
    json: bool = False,
    out: str | None = None,
    checkpoint_dir: str | None = None,
    checkpoint_every: int | None = None,
    quiet: bool = False,
) -> dict[str, Any]:
    """Solve ``problem`` (a name) and return the JSON record; writes ``out`` if given."""
    from eaco_jax.driver.minimize import minimize
    from eaco_jax.ops.constraints import check_method
    from eaco_jax.problems.constrained import float64
    from eaco_jax.strategies.continuous_eaco import TARGET_TOLERANCE, ContinuousEACO

    check_method(method)
    if max_evaluations < 1:
        raise ValueError(f"--max-evaluations must be positive, got {max_evaluations}")
    args = dict(problem=problem, method=method, seed=seed, max_evaluations=max_evaluations,
                json=json, out=out, checkpoint_every=checkpoint_every, quiet=quiet)
    with float64():
        prob = load_problem(problem)
        strategy = ContinuousEACO(constraint_method=method)
        kwargs: dict[str, Any] = {}
        accepted = inspect.signature(minimize).parameters
        if checkpoint_dir is not None:
            if "checkpoint_dir" not in accepted:
                raise ValueError("this installation's minimize() has no checkpoint support")
            kwargs.update(checkpoint_dir=checkpoint_dir, checkpoint_every=checkpoint_every,
                          run_info={"command": "constrained", "args": args})
        target = None if prob.f_star is None else prob.f_star + TARGET_TOLERANCE
        result = minimize(prob, strategy, seed=int(seed), max_evaluations=int(max_evaluations),
                          chunk_size=50, target=target, progress=not (json or quiet), **kwargs)
    state = result.state
    f = float(result.f)
    record: dict[str, Any] = {
        "problem": prob.name,
        "method": method,
        "seed": int(seed),
        "x": np.asarray(result.x).tolist(),
        "f": f,
        "violation": float(result.violation),
        "feasible": bool(result.feasible),
        "evaluations": int(np.asarray(result.evaluations)),
        "evaluations_to_target": evaluations_to_target(state),
        "f_star": prob.f_star,
        "error": None if prob.f_star is None else f - prob.f_star,
        "iterations": int(result.iterations),
        "seconds": float(result.seconds),
    }
    if out is not None:
        write_outputs(Path(out), record, result.history, prob.f_star)
    return record


def write_outputs(folder: Path, record: dict[str, Any], history: dict[str, np.ndarray],
                  f_star: float | None) -> None:
    """``result.json`` and ``convergence.png`` (best feasible f, or f - f*, vs evaluations)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    write_json(folder / "result.json", record)
    evals = np.asarray(history["evaluations"])
    best = np.asarray(history["best_f"], dtype=np.float64)
    feas = np.asarray(history["best_violation"]) <= 0
    fig, ax = plt.subplots(figsize=(6, 4))
    if f_star is not None:
        gap = np.where(feas, np.maximum(best - f_star, 1e-16), np.nan)
        ax.semilogy(evals, gap)
        ax.axhline(1e-4, color="gray", ls="--", lw=0.8, label="1e-4 (CEC2006 success)")
        ax.set_ylabel("best feasible f - f*")
        ax.legend()
    else:
        ax.plot(evals, np.where(feas, best, np.nan))
        ax.set_ylabel("best feasible f")
    ax.set_xlabel("evaluations")
    ax.set_title(f"{record['problem']} ({record['method']}, seed {record['seed']})")
    fig.tight_layout()
    fig.savefig(folder / "convergence.png", dpi=120)
    plt.close(fig)


register_runner("constrained", run_constrained)


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def constrained(
        name: Annotated[str, typer.Argument(help="g01..g13, G1..G4, or sphere/rosenbrock/...")],
        method: Annotated[str, typer.Option(help="constraint handling: deb|penalty|epsilon")] = (
            "epsilon"),
        seed: Annotated[int, typer.Option(help="random seed")] = 0,
        max_evaluations: Annotated[int, typer.Option(help="evaluation budget")] = 500_000,
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        out: Annotated[Path | None, typer.Option(help="folder for result.json + plot")] = None,
        checkpoint_dir: Annotated[Path | None, typer.Option(help="checkpoint folder")] = None,
        checkpoint_every: Annotated[int | None, typer.Option(help="iterations between "
                                                             "checkpoints")] = None,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
    ) -> None:
        """Solve a constrained problem with continuous EACO (CEC2006 success rule 1e-4)."""
        record = run_constrained(
            name, method=method, seed=seed, max_evaluations=max_evaluations, json=json_out,
            out=None if out is None else str(out),
            checkpoint_dir=None if checkpoint_dir is None else str(checkpoint_dir),
            checkpoint_every=checkpoint_every, quiet=quiet,
        )
        if json_out:
            emit_json(record)
        elif not quiet:
            for key in ("problem", "f", "f_star", "error", "violation", "feasible",
                        "evaluations", "evaluations_to_target"):
                typer.echo(f"{key}: {record[key]}")
