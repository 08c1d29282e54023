"""Tabu search on tours with 2-opt or swap moves and recently removed edges tabu.

F. Glover, "Tabu search - Part I", ORSA Journal on Computing 1 (1989) 190-206; for the TSP
with edge attributes, J. Knox, "Tabu search performance on the symmetric traveling salesman
problem", Computers & OR 21 (1994) 867-876.

One searcher per state, started from a uniform random tour. Each iteration ``num_ants``
random neighbours of the current tour are asked (2-opt segment reversals or city swaps: a
sampled neighbourhood, since the full one has O(n^2) moves). A neighbour is tabu when it adds
an edge removed less than ``tenure`` iterations ago. ``tell`` moves to the shortest non-tabu
neighbour even when it is longer than the current tour (a tabu one is allowed when it beats the
best so far: aspiration); the edges the move removed become tabu.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ConfigError
from eaco_jax.ops import pheromone
from eaco_jax.strategies import tour_base as tb
from eaco_jax.strategies.base import State, Strategy, as_params, base_fields, record_best

Array = jax.Array


@struct.dataclass
class TourTabuParams:
    tenure: Array = 3.0  # iterations a removed edge stays tabu (1-20 tried on burma14 and
    # eil51 with 10 sampled moves: shorter was better; 10 blocked too many swap moves)


@struct.dataclass
class TourTabuState(State):
    current: Array  # (n,) current tour
    current_length: Array
    tabu_until: Array  # (n, n) iteration until which adding the edge is tabu


@dataclasses.dataclass(frozen=True)
class TourTabu(Strategy):
    """Sampled-neighbourhood tabu search on tours."""

    num_ants: int = 40
    neighbourhood: str = "2opt"
    problem_kind: ClassVar[str] = "graph"

    def __post_init__(self) -> None:
        tb.check_neighbourhood(self.neighbourhood)
        if self.num_ants < 1:
            raise ConfigError("TourTabu needs num_ants >= 1")

    def default_params(self, problem: Any = None) -> TourTabuParams:
        return as_params(TourTabuParams())

    def prepare(self, problem: Any) -> Any:
        return tb.check_graph(self, problem)

    def _init(self, key: Array, problem: Any, params: TourTabuParams) -> TourTabuState:
        n = problem.dist.shape[0]
        k_tour, k_run = jax.random.split(key)
        return TourTabuState(
            **base_fields(k_run, as_params(params), jnp.arange(n, dtype=jnp.int32)),
            current=tb.random_tours(k_tour, 1, n)[0], current_length=jnp.asarray(jnp.inf),
            tabu_until=jnp.zeros((n, n), jnp.float32))

    def _ask(self, key: Array, state: TourTabuState, problem: Any):
        keys = jax.random.split(key, self.num_ants)
        moved = jax.vmap(lambda k: tb.random_move(k, state.current, self.neighbourhood))(keys)
        first = state.iteration == 0  # the first colony: the start tour and its neighbours
        return jnp.where(first, moved.at[0].set(state.current), moved), state

    def _tell(self, state: TourTabuState, solutions: Array, fitness: Array,
              problem: Any) -> tuple[TourTabuState, dict[str, Array]]:
        lengths = fitness.astype(jnp.float32)
        n = solutions.shape[1]
        it = state.iteration.astype(jnp.float32)
        nxt = jnp.roll(solutions, -1, axis=1)
        tabu = jnp.any(state.tabu_until[solutions, nxt] > it, axis=1)
        allowed = ~tabu | (lengths < state.best_cost)
        i = jnp.argmin(jnp.where(allowed, lengths, jnp.inf))
        move = allowed[i]
        old = pheromone.edge_mask(state.current[None], n)
        new = pheromone.edge_mask(solutions[i][None], n)
        until = jnp.where(old & ~new, it + state.params.tenure, state.tabu_until)
        until = jnp.where(new, 0.0, until)
        state = state.replace(
            current=jnp.where(move, solutions[i], state.current),
            current_length=jnp.where(move, lengths[i], state.current_length),
            tabu_until=jnp.where(move, until, state.tabu_until))
        state = record_best(state, solutions, lengths)
        return state, {"tabu_fraction": jnp.mean(tabu)}
