"""The strategy contract every colony in eaco_jax follows (optax / evosax style).

A strategy is a frozen, hashable object holding *static* configuration only (number of ants,
which mechanisms exist at all, array shapes). Everything that may change between runs of the
same compiled program - hyper-parameters, pheromone, archive, PRNG key - lives in a
:class:`State` pytree, so `jit`, `vmap` (over seeds or hyper-parameters) and `lax.scan` (over
iterations) apply to the pure functions

    state = strategy.init(key, problem, params)
    solutions, state = strategy.ask(key, state)
    state = strategy.tell(state, solutions, fitness)

``fitness`` is whatever ``problem.evaluate(solutions)`` returns (see :mod:`eaco_jax.problems.base`).
The hyper-parameters are stored in ``state.params`` so a batch of states built from a batch of
params is a vmappable sweep.

Subclasses implement ``_init``, ``_ask`` and ``_tell``; the base keeps the best-so-far record,
the iteration / evaluation counters and the per-iteration statistics in one place, maps NaN
costs to +inf once, and jits the public methods with ``self`` static.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

Array = jax.Array
PyTree = Any

HISTORY_FIELDS = ("best_cost", "iter_best_cost", "iter_mean_cost", "diversity")


@struct.dataclass
class State:
    """Fields every colony state carries. Strategies subclass this with their own fields.

    Attributes:
      key: the run's PRNG key stream; the driver splits one key per iteration from it.
      params: the strategy's hyper-parameters (a traced pytree, vmappable).
      iteration: completed ask/tell rounds.
      evaluations: solutions evaluated so far.
      best_solution: best solution found so far (minimisation).
      best_cost: its scalar cost (for constrained problems: its objective value).
      iter_best_cost / iter_mean_cost: statistics of the last iteration's ants.
      diversity: population diversity of the last iteration (strategy-defined, in [0, 1]).
      stagnation: iterations since best_cost last improved.
    """

    key: Array
    params: PyTree
    iteration: Array
    evaluations: Array
    best_solution: Array
    best_cost: Array
    iter_best_cost: Array
    iter_mean_cost: Array
    diversity: Array
    stagnation: Array


def base_fields(key: Array, params: PyTree, solution_template: Array) -> dict[str, Any]:
    """Initial values of the :class:`State` fields, for a subclass's ``_init``."""
    f32 = jnp.float32
    return dict(
        key=key,
        params=params,
        iteration=jnp.zeros((), jnp.int32),
        evaluations=jnp.zeros((), jnp.int32),
        best_solution=solution_template,
        best_cost=jnp.array(jnp.inf, f32),
        iter_best_cost=jnp.array(jnp.inf, f32),
        iter_mean_cost=jnp.array(jnp.inf, f32),
        diversity=jnp.zeros((), f32),
        stagnation=jnp.zeros((), jnp.int32),
    )


def _jit_method(fn):
    """jit a strategy method with ``self`` static (strategies are frozen dataclasses)."""
    return functools.wraps(fn)(jax.jit(fn, static_argnums=0))


@dataclasses.dataclass(frozen=True)
class Strategy:
    """Base class. Subclasses are ``@dataclasses.dataclass(frozen=True)`` with static fields.

    Subclass hooks:
      default_params(problem) -> Params pytree
      _init(key, problem, params) -> State
      _ask(key, state) -> (solutions, state)
      _tell(state, solutions, fitness) -> State   (update best-so-far via ``record_best``)
      scalar_cost(fitness) -> (m,) float32 used for statistics and the best-so-far record.
    """

    num_ants: int = 40
    #: which problem kinds the strategy solves ("graph" or "continuous")
    problem_kind: ClassVar[str] = ""

    # ----------------------------------------------------------------- subclass hooks
    def default_params(self, problem: Any) -> PyTree:
        raise NotImplementedError(f"{type(self).__name__} must define default_params")

    def _init(self, key: Array, problem: Any, params: PyTree) -> State:
        raise NotImplementedError(f"{type(self).__name__} must define _init")

    def _ask(self, key: Array, state: State) -> tuple[Array, State]:
        raise NotImplementedError(f"{type(self).__name__} must define _ask")

    def _tell(self, state: State, solutions: Array, fitness: PyTree) -> State:
        raise NotImplementedError(f"{type(self).__name__} must define _tell")

    def scalar_cost(self, fitness: PyTree) -> Array:
        """Per-ant scalar cost used for statistics (default: fitness itself)."""
        return fitness

    def stats(self, state: State) -> dict[str, Array]:
        """Per-iteration statistics the driver records as history (extend in subclasses)."""
        return {name: getattr(state, name) for name in HISTORY_FIELDS}

    # ----------------------------------------------------------------- public, jitted
    def init(self, key: Array, problem: Any, params: PyTree | None = None) -> State:
        """Fresh colony state for ``problem``. ``params=None`` takes ``default_params``."""
        if params is None:
            params = self.default_params(problem)
        return self._init_jit(key, problem, params)

    @_jit_method
    def _init_jit(self, key: Array, problem: Any, params: PyTree) -> State:
        return self._init(key, problem, params)

    @_jit_method
    def ask(self, key: Array, state: State) -> tuple[Array, State]:
        """Construct one colony of candidate solutions (shape ``(num_ants, ...)``)."""
        return self._ask(key, state)

    @_jit_method
    def tell(self, state: State, solutions: Array, fitness: PyTree) -> State:
        """Update the colony with the evaluated ``solutions``; NaN costs count as +inf."""
        fitness = jax.tree.map(lambda f: jnp.where(jnp.isnan(f), jnp.inf, f), fitness)
        state = self._tell(state, solutions, fitness)
        cost = self.scalar_cost(fitness)
        finite = jnp.isfinite(cost)
        n_finite = jnp.maximum(finite.sum(), 1)
        return state.replace(
            iteration=state.iteration + 1,
            evaluations=state.evaluations + solutions.shape[0],
            iter_best_cost=jnp.min(cost).astype(jnp.float32),
            iter_mean_cost=(jnp.where(finite, cost, 0.0).sum() / n_finite).astype(jnp.float32),
        )


def record_best(state: State, solutions: Array, cost: Array) -> State:
    """Update best-so-far with the lowest-cost ant of ``solutions`` (plain minimisation)."""
    i = jnp.argmin(cost)
    improved = cost[i] < state.best_cost
    return state.replace(
        best_solution=jnp.where(improved, solutions[i], state.best_solution),
        best_cost=jnp.where(improved, cost[i], state.best_cost).astype(jnp.float32),
        stagnation=jnp.where(improved, 0, state.stagnation + 1),
    )
