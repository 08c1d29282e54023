"""What the continuous baselines share with ContinuousEACO: constraint handling and the record.

Every continuous baseline (PSO, real-coded GA, simulated annealing, tabu search) compares
solutions exactly as :class:`~eaco_jax.strategies.continuous_eaco.ContinuousEACO` does, with
one of the three orders of :mod:`eaco_jax.ops.constraints` (``"epsilon"``, ``"deb"``,
``"penalty"``) and the same epsilon schedule (epsilon(0) from the first colony, then
Takahama & Sakai's decay to 0 at ``eps_cutoff`` iterations). The best-so-far is kept by Deb's
rules (feasible first), ``best_cost`` is the best feasible objective (+inf before one is found),
and ``target_evaluations`` records when f - f* <= 1e-4 was first met on a feasible point (the
CEC2006 success rule), as ContinuousEACO records it, so the same experiment scripts read both.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ProblemError
from eaco_jax.ops import constraints as ch
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import State, base_fields

Array = jax.Array

#: CEC2006 success rule: feasible and f - f* <= this (as in ContinuousEACO)
TARGET_TOLERANCE = 1e-4


@struct.dataclass
class ConstraintParams:
    """Constraint-handling parameters (the same names and defaults as ContinuousParams)."""

    penalty: Array = 0.3  # PEN of the static penalty method
    eps_fraction: Array = 0.2  # eps(0) = violation at this quantile of the first colony
    eps_cutoff: Array = 50.0  # Tc: iterations after which eps = 0
    eps_exponent: Array = 5.0  # cp of the epsilon schedule


@struct.dataclass
class ConstrainedState(State):
    """Base state of the continuous baselines: the epsilon level and the constrained record."""

    epsilon0: Array
    epsilon: Array
    best_f: Array
    best_violation: Array
    target_evaluations: Array
    target_iteration: Array


def constrained_fields(key: Array, params: Any, problem: Any) -> dict[str, Any]:
    """Initial values of the :class:`ConstrainedState` fields (nothing evaluated)."""
    dtype = problem.dtype
    return dict(
        **base_fields(key, params, jnp.asarray((problem.lower + problem.upper) / 2, dtype)),
        epsilon0=jnp.zeros((), dtype),
        epsilon=jnp.zeros((), dtype),
        best_f=jnp.asarray(jnp.inf, dtype),
        best_violation=jnp.asarray(jnp.inf, dtype),
        target_evaluations=jnp.asarray(-1, jnp.int32),
        target_iteration=jnp.asarray(-1, jnp.int32),
    )


def check_continuous(strategy: Any, problem: Any) -> Any:
    """``problem`` if it is continuous with box bounds, else a :class:`ProblemError`."""
    if getattr(problem, "kind", None) != "continuous" or not hasattr(problem, "lower"):
        raise ProblemError(
            f"{type(strategy).__name__} needs a continuous problem with box bounds, got "
            f"{type(problem).__name__}")
    return problem


def epsilon_level(state: ConstrainedState, v: Array, params: Any,
                  method: str) -> tuple[ConstrainedState, Array]:
    """The state with epsilon(0) set at the first tell, and this iteration's epsilon."""
    if method != "epsilon":
        return state, state.epsilon
    first = ch.initial_epsilon(v, params.eps_fraction).astype(state.epsilon0.dtype)
    state = state.replace(epsilon0=jnp.where(state.iteration == 0, first, state.epsilon0))
    eps = ch.epsilon_schedule(state.iteration + 1, state.epsilon0, params.eps_cutoff,
                              params.eps_exponent).astype(state.epsilon.dtype)
    return state.replace(epsilon=eps), eps


def record(state: ConstrainedState, x: Array, fitness: Evaluation,
           problem: Any) -> tuple[ConstrainedState, dict[str, Array]]:
    """Best-so-far by Deb's rules, ``best_cost``, stagnation and the CEC2006 target record.

    Returns the state and the metrics every continuous strategy reports.
    """
    f = fitness.f.astype(state.best_f.dtype)
    v = fitness.violation.astype(state.best_violation.dtype)
    i = ch.rank_order(f, v, "deb")[0]
    improved = ch.better(f[i], v[i], state.best_f, state.best_violation, "deb")
    best_f = jnp.where(improved, f[i], state.best_f)
    best_v = jnp.where(improved, v[i], state.best_violation)
    evaluations = state.evaluations + x.shape[0]
    target_evals, target_iter = state.target_evaluations, state.target_iteration
    f_star = getattr(problem, "f_star", None)
    if f_star is not None:
        hit = (best_v <= 0) & (best_f - f_star <= TARGET_TOLERANCE) & (target_evals < 0)
        target_evals = jnp.where(hit, evaluations, target_evals)
        target_iter = jnp.where(hit, state.iteration + 1, target_iter)
    state = state.replace(
        best_f=best_f,
        best_violation=best_v,
        best_solution=jnp.where(improved, x[i].astype(state.best_solution.dtype),
                                state.best_solution),
        best_cost=jnp.where(best_v > 0, jnp.inf, best_f).astype(jnp.float32),
        stagnation=jnp.where(improved, 0, state.stagnation + 1),
        target_evaluations=target_evals,
        target_iteration=target_iter,
    )
    metrics = {"best_f": best_f, "best_violation": best_v, "evaluations": evaluations,
               "epsilon": state.epsilon}
    return state, metrics


def feasible_cost(fitness: Evaluation) -> Array:
    """Objective of feasible solutions, +inf for infeasible ones (iteration statistics)."""
    return jnp.where(fitness.violation > 0, jnp.inf, fitness.f).astype(jnp.float32)


def better(f_a: Array, v_a: Array, f_b: Array, v_b: Array, method: str, eps: Array,
           params: Any) -> Array:
    """True where a beats b under ``method`` (:func:`eaco_jax.ops.constraints.better`)."""
    return ch.better(f_a, v_a, f_b, v_b, method, eps, params.penalty)


def energy_difference(f_new: Array, v_new: Array, f_old: Array, v_old: Array, method: str,
                      eps: Array, params: Any, v_scale: Array) -> Array:
    """A scalar "how much worse" for Metropolis-type acceptance under ``method``.

    penalty: the difference of f + PEN v. deb / epsilon: when the primary keys (violation
    beyond epsilon) differ, their difference times ``v_scale`` (objective units per unit of
    violation); otherwise the objective difference.
    """
    pn, sn = ch.sort_keys(f_new, v_new, method, eps, params.penalty)
    po, so = ch.sort_keys(f_old, v_old, method, eps, params.penalty)
    if method == "penalty":
        return pn - po
    d = jnp.where(pn != po, (pn - po) * v_scale, sn - so)
    return jnp.where(jnp.isnan(d), jnp.inf, d)
