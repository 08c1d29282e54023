"""The :class:`Result` of a run, built on the host from the final state and the history, with
the returned solution re-checked by the problem (``host_check``)."""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np

from eaco_jax.driver.history import merge_history
from eaco_jax.driver.precision import float_leaves
from eaco_jax.driver.programs import NAN_KEY
from eaco_jax.errors import ProblemError
from eaco_jax.strategies.base import State, Strategy


@dataclasses.dataclass
class Result:
    """What :func:`minimize` returns. With several rows (seeds, settings) every array has a
    leading row axis.

    ``history`` maps a metric name to an array over iterations (best so far, iteration best,
    iteration mean, diversity, plus strategy-specific metrics; with ``max_evaluations`` a row
    that stopped before the others has NaN there). ``stop_reason`` says why the run ended:
    ``"iterations"`` (the iteration budget), ``"max_evaluations"`` (the next iteration could
    have charged more than the budget left), ``"interrupted"`` or the name of the stop rule
    that fired. ``evaluations`` is what each row was charged (the colony plus what a strategy
    charges itself, e.g. gradient repair), never more than ``max_evaluations``.
    ``compile_seconds`` is what this call spent compiling or loading programs (the initial
    state's and the chunks'; 0 when the process had them), ``seconds`` that plus compute.
    ``host_seconds`` is the host's work between the compiled chunks (reading each chunk's
    history, stop rules, progress, checkpoints): wall time of the chunk loop that is neither
    compute nor compilation, during which the device waits.

    The returned solution is re-checked on the host: ``best_cost`` is a TSP tour's exact
    length, and for constrained problems ``f``, ``violation`` and ``feasible`` come from a
    float64 evaluation of ``x`` (``feasible``: every inequality ``g(x) <= tolerance["inequality"]``
    and every ``|h(x)| <= tolerance["equality"]``).
    """

    best_solution: np.ndarray
    best_cost: np.ndarray
    history: dict[str, np.ndarray]
    iterations: int
    evaluations: np.ndarray
    seconds: float
    compile_seconds: float
    seconds_per_iteration: float
    state: State
    problem: Any
    strategy: Strategy
    seeds: list[int]
    stop_reason: str = "iterations"
    max_evaluations: int | None = None
    f: np.ndarray | None = None
    violation: np.ndarray | None = None
    feasible: np.ndarray | None = None
    tolerance: dict[str, float] | None = None
    precision: str = "float32"
    host_seconds: float = 0.0

    def __post_init__(self) -> None:
        if self.f is None:
            self.f = np.asarray(getattr(self.state, "best_f", self.best_cost))
        if self.violation is None:
            v = getattr(self.state, "best_violation", None)
            self.violation = np.zeros_like(self.best_cost) if v is None else np.asarray(v)
        if self.feasible is None:
            self.feasible = np.asarray(self.violation) <= 0

    @property
    def batched(self) -> bool:
        return len(self.seeds) > 1 or np.ndim(self.best_cost) > 0

    @property
    def x(self) -> np.ndarray:
        """The best solution (alias of ``best_solution``)."""
        return self.best_solution


def shown_best(problem: Any, best_cost: Any) -> float:
    """The best of the rows' ``best_cost`` as the user reads it: the problem's
    ``shown_best(cost)`` if it has one (a maximised fitness shows its own sign), else the cost."""
    best = float(np.min(np.asarray(best_cost)))
    shown = getattr(problem, "shown_best", None)
    return float(shown(best)) if callable(shown) else best


def make_result(strategy: Strategy, problem: Any, state: State,
                history: list[dict[str, Any]], batched: bool, seeds: list[int], reason: str,
                compile_seconds: float, run_seconds: float, iters_here: int,
                max_evaluations: int | None, host_seconds: float = 0.0) -> Result:
    """The :class:`Result`, with the returned solution re-checked on the host."""
    axis = 1 if batched else 0
    merged = merge_history(history, axis)
    merged.pop(NAN_KEY, None)
    iters_run = next(iter(merged.values())).shape[axis] if merged else 0
    best_solution = np.asarray(state.best_solution)
    best_cost = np.asarray(state.best_cost)
    checked = host_checks(problem, best_solution, batched)
    extra: dict[str, Any] = {}
    if checked:
        best_cost = _rows([c["cost"] for c in checked], batched)
        if "f" in checked[0]:
            extra["f"] = _rows([c["f"] for c in checked], batched)
            extra["violation"] = _rows([c["violation"] for c in checked], batched)
            extra["feasible"] = _rows([c["feasible"] for c in checked], batched, bool)
            extra["tolerance"] = checked[0].get("tolerance")
            _warn_feasibility(state, extra["feasible"], extra["f"], problem)
    dtypes = {x.dtype for x in float_leaves(problem)}
    return Result(
        best_solution=best_solution,
        best_cost=best_cost,
        history=merged,
        iterations=iters_run,
        evaluations=np.asarray(state.evaluations),
        seconds=compile_seconds + run_seconds,
        compile_seconds=compile_seconds,
        seconds_per_iteration=run_seconds / max(iters_here, 1),
        state=state,
        problem=problem,
        strategy=strategy,
        seeds=seeds,
        stop_reason=reason,
        max_evaluations=max_evaluations,
        precision="float64" if np.dtype("float64") in dtypes else "float32",
        host_seconds=host_seconds,
        **extra,
    )


def _rows(values: list[Any], batched: bool, dtype: Any = np.float64) -> np.ndarray:
    a = np.asarray(values, dtype)
    return a if batched else a[0]


def host_checks(problem: Any, best_solution: np.ndarray, batched: bool) -> list[dict[str, Any]]:
    """``problem.host_check`` of every row's returned solution ([] if the problem has none).

    A returned solution that is not a solution (not a permutation, outside the bounds) is a
    bug in the strategy: it raises ``RuntimeError`` rather than report a wrong result.
    """
    check = getattr(problem, "host_check", None)
    if check is None:
        return []
    out = []
    for row in (best_solution if batched else best_solution[None]):
        try:
            out.append(check(row))
        except ProblemError as err:
            raise RuntimeError(
                f"the returned best solution is not a valid solution of "
                f"{getattr(problem, 'name', '')!r}: {err} (a bug; please report it)") from None
    return out


def _warn_feasibility(state: State, feasible: np.ndarray, f: np.ndarray, problem: Any) -> None:
    """One warning line where the reported best is no solution: its objective is not finite
    (the best of the least-violating evaluations was +inf, -inf or NaN), or a point feasible
    in the run's precision violates a constraint in float64."""
    f = np.asarray(f, np.float64)
    if not np.all(np.isfinite(f)):
        name = getattr(problem, "name", type(problem).__name__)
        worst = f[~np.isfinite(f)].reshape(-1)[0]
        which = ("with the least violation found " if int(getattr(problem, "num_inequality", 0))
                 + int(getattr(problem, "num_equality", 0)) else "")
        warnings.warn(
            f"every evaluation of {name!r} {which}returned {worst} (reported feasible=False): "
            "its objective is not finite across the search box; check the function and its "
            "bounds", stacklevel=3)
    v = getattr(state, "best_violation", None)
    if v is None:
        return
    claimed = np.asarray(v) <= 0
    if np.any(claimed & ~np.asarray(feasible) & np.isfinite(f)) and getattr(
            problem, "stochastic", False):
        warnings.warn(
            f"{getattr(problem, 'name', '')!r}: the best, feasible in the randomised worlds it "
            "was evaluated in, violates a constraint in the re-check's worlds (a robust "
            "search's best is noisy: choose among finalists on more worlds, e.g. eaco gait "
            "--finalists)", stacklevel=3)
    elif np.any(claimed & ~np.asarray(feasible) & np.isfinite(f)):
        warnings.warn(
            f"{getattr(problem, 'name', '')!r}: a point feasible in the run's precision violates "
            "a constraint when re-checked in float64; run with precision='float64' (or 'auto')",
            stacklevel=3)
