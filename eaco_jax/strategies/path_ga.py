"""Genetic algorithm over waypoint sequences for start-to-goal paths (the paper's GA, Fig. 4).

The comparison the paper draws (§5, Figs. 4-7) is EACO against a GA on the same path problem;
this is that GA, on any ``kind = "path"`` problem (shortest length or least walking time).
Individuals are node sequences as the problem takes them. The first ``ask`` returns random
simple walks (the goal taken as soon as it is one edge away). Each generation: binary
tournaments pick parents; with probability ``p_crossover`` a child is the common-node
crossover of two parents (parent A to a node both visit, then parent B), else a copy of
parent A; with probability ``p_mutation`` one waypoint edit follows (replace, delete or insert a
node, kept only where the new edges exist). Elitism: the ``elites`` best of the previous
population replace the worst children. No local search: the operators are the GA's own.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ConfigError
from eaco_jax.ops.path_ops import common_node_crossover, mutate, path_diversity, random_walk
from eaco_jax.problems.path_planning import GOAL, START
from eaco_jax.strategies.base import (
    UNIT,
    Range,
    State,
    Strategy,
    as_params,
    base_fields,
    record_best,
)

Array = jax.Array


@struct.dataclass
class PathGAParams:
    """Traced rates (names shared with the other strategies' crossover and mutation)."""

    p_crossover: Array = 0.8
    p_mutation: Array = 0.3

    RANGES: ClassVar[dict[str, Range]] = {"p_crossover": UNIT, "p_mutation": UNIT}


@struct.dataclass
class PathGAState(State):
    pop: Array  # (m, n) the evaluated population (initially unevaluated: cost inf)
    pop_cost: Array  # (m,)


@dataclasses.dataclass(frozen=True)
class PathGA(Strategy):
    """Generational path GA: ``num_ants`` individuals, tournaments, crossover, mutation,
    elitism."""

    num_ants: int = 32
    tournament_size: int = 2
    elites: int = 1
    problem_kind: ClassVar[str] = "path"

    def __post_init__(self) -> None:
        if self.num_ants < 2 or self.tournament_size < 1:
            raise ConfigError("PathGA needs num_ants >= 2 and tournament_size >= 1")
        if not 0 <= self.elites < self.num_ants:
            raise ConfigError(f"PathGA elites must be in [0, num_ants={self.num_ants})")

    def default_params(self, problem: Any = None) -> PathGAParams:
        return as_params(PathGAParams())

    def _init(self, key: Array, problem: Any, params: PathGAParams) -> PathGAState:
        n = problem.n
        key, k_pop = jax.random.split(key)
        cost = problem.step_cost
        pop = jax.vmap(random_walk, in_axes=(0, None))(jax.random.split(k_pop, self.num_ants),
                                                       cost)
        template = jnp.full((n,), GOAL, jnp.int32).at[0].set(START)
        return PathGAState(**base_fields(key, params, template), pop=pop,
                           pop_cost=jnp.full((self.num_ants,), jnp.inf, jnp.float32))

    def _ask(self, key: Array, state: PathGAState, problem: Any) -> tuple[Array, PathGAState]:
        p = state.params
        m = self.num_ants
        k_sel, k_cross, k_do, k_mut, k_domut = jax.random.split(key, 5)
        entrants = jax.random.randint(k_sel, (2, m, self.tournament_size), 0, m)
        scores = state.pop_cost[entrants]
        winners = jnp.take_along_axis(entrants, jnp.argmin(scores, axis=-1)[..., None], -1)[..., 0]
        a, b = state.pop[winners[0]], state.pop[winners[1]]
        kids = jax.vmap(common_node_crossover)(jax.random.split(k_cross, m), a, b)
        kids = jnp.where((jax.random.uniform(k_do, (m,)) < p.p_crossover)[:, None], kids, a)
        mutated = jax.vmap(mutate, in_axes=(0, 0, None))(jax.random.split(k_mut, m), kids,
                                                         problem.step_cost)
        kids = jnp.where((jax.random.uniform(k_domut, (m,)) < p.p_mutation)[:, None], mutated,
                         kids)
        first = state.iteration == 0  # the initial population is evaluated first
        return jnp.where(first, state.pop, kids).astype(jnp.int32), state

    def _tell(self, state: PathGAState, paths: Array, cost: Array,
              problem: Any) -> tuple[PathGAState, dict[str, Array]]:
        state = record_best(state, paths, cost)
        first = state.iteration == 0
        keep = jnp.argsort(state.pop_cost)[: self.elites]
        worst = jnp.argsort(-cost)[: self.elites]  # +inf (dead) children go first
        new_pop = paths.at[worst].set(state.pop[keep])
        new_cost = cost.at[worst].set(state.pop_cost[keep])
        pop = jnp.where(first, paths, new_pop)
        pop_cost = jnp.where(first, cost, new_cost).astype(jnp.float32)
        return state.replace(pop=pop, pop_cost=pop_cost), {
            "diversity": path_diversity(paths, paths.shape[1])}
