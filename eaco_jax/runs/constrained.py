"""The ``constrained`` run: a CEC2006 problem (or a test function) with continuous EACO.

Runs in 64-bit precision (:func:`eaco_jax.problems.float64`, scoped to the run): the CEC2006
success rule f - f* <= 1e-4 is finer than float32's spacing at |f| ~ 7000 (g10). The run stops
after the chunk in which the target f* + 1e-4 is reached (or at the budget).
Outputs in ``out``: ``result.json`` and ``convergence.png``.
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

#: unconstrained test functions also accepted as the problem name (dimension 10)
FUNCTIONS = ("sphere", "rosenbrock", "rastrigin", "ackley")
METHODS = ("epsilon", "deb", "penalty")


#: the evaluation budget of a run given neither --iterations, --max-evaluations nor
#: --max-seconds
EVALUATIONS = 500_000


@dataclasses.dataclass(frozen=True)
class ConstrainedSettings:
    problem: str = setting("g01", "g01..g13, G1..G4, or sphere/rosenbrock/rastrigin/ackley",
                           positional=True, metavar="NAME")
    method: str = setting("epsilon", "constraint handling", choices=METHODS)
    seed: int = setting(0, "random seed")
    ants: int = setting(20, "colony size")
    archive_size: int = setting(30, "solutions kept in the ranked archive (the pheromone)")
    max_evaluations: int | None = setting(None, f"evaluation budget (default {EVALUATIONS:,}; "
                                          "with --max-seconds alone, no cap: time ends the "
                                          "run; or give --iterations)")
    iterations: int | None = setting(None, "iteration budget instead of --max-evaluations")
    repair_steps: int = setting(3, "gradient-repair steps per infeasible ant (0: none)")
    refine_ants: int = setting(4, "SQP refinement ants per iteration (0: derivative-free)")
    max_seconds: float | None = setting(None, "stop after this many compute seconds")
    params: str | None = setting(None, PARAMS_HELP)
    out: str | None = setting(None, "folder for result.json and convergence.png")

    def __post_init__(self) -> None:
        from eaco_jax.errors import ConfigError

        if self.method not in METHODS:
            raise ConfigError(f"method={self.method!r} is not one of {', '.join(METHODS)}")
        check_settings(self, "ants", "archive_size", "max_evaluations", "iterations")
        if self.iterations is not None and self.max_evaluations is not None:
            object.__setattr__(self, "max_evaluations", None)  # --iterations wins
        if self.repair_steps < 0 or not 0 <= self.refine_ants <= self.ants:
            raise ConfigError(
                f"repair_steps must be >= 0 and refine_ants in [0, ants={self.ants}], got "
                f"{self.repair_steps} and {self.refine_ants}")


def load_problem(name: str) -> Any:
    """A CEC2006 problem (g01-g13, G1-G4) or a test function by name; ProblemError if unknown."""
    from eaco_jax.errors import ProblemError
    from eaco_jax.problems import cec2006, functions

    if name.lower() in FUNCTIONS:
        return getattr(functions, name.lower())()
    try:
        return cec2006(name)
    except ProblemError as err:
        raise ProblemError(f"{err.args[0]}, or a test function ({', '.join(FUNCTIONS)})") from None


def build(s: ConstrainedSettings) -> Built:
    from eaco_jax.problems.constrained import float64
    from eaco_jax.strategies.continuous_eaco import TARGET_TOLERANCE, ContinuousEACO

    with float64():
        problem = load_problem(s.problem)
        strategy = ContinuousEACO(num_ants=int(s.ants), archive_size=int(s.archive_size),
                                  constraint_method=s.method, repair_steps=int(s.repair_steps),
                                  refine_ants=int(s.refine_ants))
        params = params_from(strategy, problem, s.params)
    budget: dict[str, Any] = {
        **budget_of(s, s.iterations, {"max_evaluations": EVALUATIONS}), "chunk_size": 50}
    if problem.f_star is not None:
        budget["target"] = problem.f_star + TARGET_TOLERANCE
    return Built(problem, strategy, params, budget, context=float64)


def row_metrics(built: Built, result: Any, row: int) -> dict[str, Any]:
    from eaco_jax.strategies.continuous_eaco import TARGET_TOLERANCE

    f = float(np.asarray(result.f).reshape(-1)[row])
    v = float(np.asarray(result.violation).reshape(-1)[row])
    out: dict[str, Any] = {"f": f, "violation": v, "feasible": bool(v <= 0.0)}
    f_star = built.problem.f_star
    if f_star is not None:
        out["error"] = f - float(f_star)
        out["success"] = bool(v <= 0.0 and f - float(f_star) <= TARGET_TOLERANCE)
    return out


def evaluations_to_target(state: Any) -> int | None:
    """First evaluation count with a feasible f - f* <= 1e-4, or None."""
    value = int(np.asarray(state.target_evaluations))
    return value if value >= 0 else None


def run(s: ConstrainedSettings, *, progress: bool = False,
        checkpointing: Any = None) -> dict[str, Any]:
    """Solve the problem; returns the JSON record and writes ``s.out`` if set."""
    from eaco_jax.driver.minimize import minimize

    check_out(s.out)
    built = build(s)
    with entered(built):
        result = minimize(built.problem, built.strategy, seed=int(s.seed), progress=progress,
                          checkpointing=checkpointing, params=built.params, **built.budget)
    prob = built.problem
    f = float(result.f)
    record: dict[str, Any] = {
        "problem": prob.name,
        "method": s.method,
        "seed": int(s.seed),
        "x": np.asarray(result.x).tolist(),
        "f": f,
        "violation": float(result.violation),
        "feasible": bool(result.feasible),
        "feasibility_tolerance": result.tolerance,
        "evaluations": int(np.asarray(result.evaluations)),
        "max_evaluations": result.max_evaluations,
        "evaluations_to_target": evaluations_to_target(result.state),
        "f_star": prob.f_star,
        "error": None if prob.f_star is None else f - prob.f_star,
        "iterations": int(result.iterations),
        "stop_reason": result.stop_reason,
        "seconds": float(result.seconds),
        "compile_seconds": float(result.compile_seconds),
    }
    if s.out is not None:
        write_outputs(Path(s.out), record, result.history, prob.f_star)
    return record


def write_outputs(folder: Path, record: dict[str, Any], history: dict[str, np.ndarray],
                  f_star: float | None) -> None:
    """``result.json`` and ``convergence.png`` (best feasible f, or f - f*, vs evaluations)."""
    from eaco_jax import plots
    from eaco_jax.outputs import write_json

    write_json(folder / "result.json", record)
    plots.constrained_convergence(
        history, folder / "convergence.png", f_star=f_star,
        title=f"{record['problem']} ({record['method']}, seed {record['seed']})")


def summary(record: dict[str, Any]) -> str:
    """The run in one line: f (against f* where known), feasibility, evaluations, time."""
    error = record.get("error")
    known = (f" (f* {record['f_star']:.10g}, error {error:.3g})" if error is not None else "")
    feasible = ("feasible" if record["feasible"] else
                f"infeasible (violation {record['violation']:.3g})")
    target = record.get("evaluations_to_target")
    reached = f", target reached after {target}" if target is not None else ""
    return (f"{record['problem']}: f {record['f']:.10g}{known}, {feasible}, "
            f"{record['evaluations']} evaluations{reached}, {record['seconds']:.1f} s")


KIND = RunKind("constrained", ConstrainedSettings, build, run, row_metrics, summary)
