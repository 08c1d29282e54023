"""Simulated annealing on tours: a population of independent chains with 2-opt or swap moves.

S. Kirkpatrick, C. D. Gelatt, M. P. Vecchi, "Optimization by simulated annealing", Science 220
(1983) 671-680; V. Cerny, "Thermodynamical approach to the traveling salesman problem", JOTA
45 (1985) 41-51 (the TSP with segment-reversal moves).

Each ant is one Metropolis chain started from a uniform random tour. A proposal is one random
2-opt move (reverse a segment) or swap of two cities (``neighbourhood``); it is accepted when
not longer, else with probability exp(-Delta / T). T falls geometrically from ``t0`` to
``t_final`` over ``anneal_iterations`` iterations, in units of the first colony's mean edge
length (L / n). Every proposal is one evaluated tour, so budgets compare with the colonies at
equal tours built (an implementation for speed would evaluate Delta in O(1)).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ConfigError
from eaco_jax.strategies import tour_base as tb
from eaco_jax.strategies.base import State, Strategy, as_params, base_fields, record_best

Array = jax.Array


@struct.dataclass
class TourSAParams:
    t0: Array = 1.0  # initial temperature, in mean edge lengths of the first colony
    t_final: Array = 0.005
    anneal_iterations: Array = 1000.0  # iterations from t0 to t_final (then constant)


@struct.dataclass
class TourSAState(State):
    tours: Array  # (m, n) current tour of each chain
    lengths: Array  # (m,) their lengths (+inf before the first tell)
    edge_unit: Array  # mean edge length of the first colony
    uniform: Array  # (m,) acceptance draws of the asked proposals


@dataclasses.dataclass(frozen=True)
class TourAnnealing(Strategy):
    """``num_ants`` independent annealing chains on tours."""

    num_ants: int = 40
    neighbourhood: str = "2opt"
    problem_kind: ClassVar[str] = "graph"

    def __post_init__(self) -> None:
        tb.check_neighbourhood(self.neighbourhood)
        if self.num_ants < 1:
            raise ConfigError("TourAnnealing needs num_ants >= 1")

    def default_params(self, problem: Any = None) -> TourSAParams:
        return as_params(TourSAParams())

    def prepare(self, problem: Any) -> Any:
        return tb.check_graph(self, problem)

    def _init(self, key: Array, problem: Any, params: TourSAParams) -> TourSAState:
        n = problem.dist.shape[0]
        k_tours, k_run = jax.random.split(key)
        m = self.num_ants
        return TourSAState(
            **base_fields(k_run, as_params(params), jnp.arange(n, dtype=jnp.int32)),
            tours=tb.random_tours(k_tours, m, n), lengths=jnp.full((m,), jnp.inf),
            edge_unit=jnp.ones(()), uniform=jnp.zeros((m,)))

    def _ask(self, key: Array, state: TourSAState, problem: Any) -> tuple[Array, TourSAState]:
        k_move, k_accept = jax.random.split(key)
        keys = jax.random.split(k_move, self.num_ants)
        moved = jax.vmap(lambda k, t: tb.random_move(k, t, self.neighbourhood))(keys,
                                                                                 state.tours)
        u = jax.random.uniform(k_accept, (self.num_ants,))
        tours = jnp.where(state.iteration == 0, state.tours, moved)
        return tours, state.replace(uniform=u)

    def temperature(self, state: TourSAState) -> Array:
        p = state.params
        frac = jnp.clip(state.iteration / jnp.maximum(p.anneal_iterations, 1.0), 0.0, 1.0)
        return state.edge_unit * p.t0 * (p.t_final / p.t0) ** frac

    def _tell(self, state: TourSAState, solutions: Array, fitness: Array,
              problem: Any) -> tuple[TourSAState, dict[str, Array]]:
        lengths = fitness.astype(jnp.float32)
        first = state.iteration == 0
        n = solutions.shape[1]
        unit = jnp.where(first, jnp.mean(jnp.where(jnp.isfinite(lengths), lengths, 0.0)) / n,
                         state.edge_unit)
        state = state.replace(edge_unit=unit)
        t = self.temperature(state)
        delta = lengths - state.lengths
        accept = first | (delta <= 0) | (state.uniform < jnp.exp(-delta / t))
        state = state.replace(tours=jnp.where(accept[:, None], solutions, state.tours),
                              lengths=jnp.where(accept, lengths, state.lengths))
        state = record_best(state, solutions, lengths)
        return state, {"temperature": t, "acceptance": jnp.mean(accept)}
