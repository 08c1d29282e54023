"""Random search: the floor every strategy must beat at the same number of evaluations.

``RandomSearch`` draws ``num_ants`` points uniformly in the box per iteration (continuous
problems, with the constrained record of :mod:`eaco_jax.strategies.continuous_base`);
``RandomTours`` draws ``num_ants`` uniform random permutations (graph problems). Neither
learns anything; they are the reference of the baseline tests and of the paper experiments.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies import continuous_base as cb
from eaco_jax.strategies.base import State, Strategy, as_params, base_fields, record_best

Array = jax.Array


@struct.dataclass
class RandomParams(cb.ConstraintParams):
    pass


@dataclasses.dataclass(frozen=True)
class RandomSearch(Strategy):
    """Uniform sampling in the box (continuous problems)."""

    num_ants: int = 40
    problem_kind: ClassVar[str] = "continuous"

    def default_params(self, problem: Any = None) -> RandomParams:
        return as_params(RandomParams())

    def prepare(self, problem: Any) -> Any:
        return cb.check_continuous(self, problem)

    def _init(self, key: Array, problem: Any, params: RandomParams) -> cb.ConstrainedState:
        return cb.ConstrainedState(
            **cb.constrained_fields(key, as_params(params, problem.dtype), problem))

    def _ask(self, key: Array, state: cb.ConstrainedState, problem: Any):
        lo, hi = problem.lower, problem.upper
        u = jax.random.uniform(key, (self.num_ants, problem.dim), problem.dtype)
        return lo + (hi - lo) * u, state

    def _tell(self, state: cb.ConstrainedState, solutions: Array, fitness: Evaluation,
              problem: Any):
        return cb.record(state, solutions, fitness, problem)

    def scalar_cost(self, fitness: Evaluation) -> Array:
        return cb.feasible_cost(fitness)


@struct.dataclass
class NoParams:
    pass


@dataclasses.dataclass(frozen=True)
class RandomTours(Strategy):
    """Uniform random permutations (graph problems)."""

    num_ants: int = 40
    problem_kind: ClassVar[str] = "graph"

    def default_params(self, problem: Any = None) -> NoParams:
        return NoParams()

    def _init(self, key: Array, problem: Any, params: NoParams) -> State:
        n = problem.dist.shape[0]
        return State(**base_fields(key, params, jnp.arange(n, dtype=jnp.int32)))

    def _ask(self, key: Array, state: State, problem: Any):
        n = problem.dist.shape[0]
        keys = jax.random.split(key, self.num_ants)
        tours = jax.vmap(lambda k: jax.random.permutation(k, n))(keys).astype(jnp.int32)
        return tours, state

    def _tell(self, state: State, solutions: Array, fitness: Array, problem: Any):
        return record_best(state, solutions, fitness.astype(jnp.float32)), {}
