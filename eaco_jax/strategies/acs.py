"""Ant colony system (ACS) on a construction graph.

M. Dorigo, L. M. Gambardella, "Ant colony system: a cooperative learning approach to the
traveling salesman problem", IEEE TEC 1 (1997) 53-66; parameters as in Dorigo & Stuetzle,
"Ant Colony Optimization", MIT Press 2004, Table 3.6: q0 = 0.9, beta = 2, rho = xi = 0.1,
m = 10, tau0 = 1 / (n L_nn).

* Construction: the pseudo-random proportional rule (greedy with probability q0, else Eq. 2).
* Local update, toward tau0 on the edges the ants used: tau <- (1 - xi) tau + xi tau0, once per
  ant that used the edge. In the original every ant applies it right after each step, so later
  ants of the same iteration see it; here the colony is built in one batched scan, and the
  update is applied after construction (the "parallel" ACS variant), each edge decaying by
  (1 - xi)^(number of ants that used it).
* Global update on the best-so-far tour only: tau <- (1 - rho) tau + rho / L_bs on its edges
  (no evaporation elsewhere).

The paper's Eq. 68-70 is *not* this local rule (it deposits sum_k Q / L_k); GraphEACO has that.
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
class ACSParams:
    alpha: Array = 1.0
    beta: Array = 2.0
    q0: Array = 0.9
    rho: Array = 0.1  # global evaporation
    xi: Array = 0.1  # local evaporation


@struct.dataclass
class ACSState(State):
    tau: Array
    tau0: Array


@dataclasses.dataclass(frozen=True)
class AntColonySystem(Strategy):
    """ACS colony (parallel local update, see the module docstring)."""

    num_ants: int = 10
    local_search: str = "none"
    candidate_lists: bool = True
    problem_kind: ClassVar[str] = "graph"

    def __post_init__(self) -> None:
        tb.check_local_search(self.local_search)
        if self.num_ants < 1:
            raise ConfigError("AntColonySystem needs num_ants >= 1")

    def default_params(self, problem: Any = None) -> ACSParams:
        return as_params(ACSParams())

    def prepare(self, problem: Any) -> Any:
        return tb.check_graph(self, problem)

    def _init(self, key: Array, problem: Any, params: ACSParams) -> ACSState:
        n = problem.dist.shape[0]
        tau0 = 1.0 / (n * tb.nearest_neighbour_length(problem))
        return ACSState(**base_fields(key, as_params(params), jnp.arange(n, dtype=jnp.int32)),
                        tau=jnp.full((n, n), tau0, jnp.float32), tau0=tau0)

    def _ask(self, key: Array, state: ACSState, problem: Any) -> tuple[Array, ACSState]:
        p = state.params
        tours = tb.build(key, state.tau, problem, self.num_ants, p.alpha, p.beta, p.q0,
                         self.candidate_lists)
        return tb.improve(tours, problem, self.local_search), state

    def _tell(self, state: ACSState, solutions: Array, fitness: Array,
              problem: Any) -> tuple[ACSState, dict[str, Array]]:
        p = state.params
        n = state.tau.shape[0]
        lengths = fitness.astype(jnp.float32)
        uses = pheromone.edge_sum(solutions, jnp.ones_like(lengths), n)
        # the local rule applied `uses` times: tau0 + (tau - tau0) (1 - xi)^uses
        tau = state.tau0 + (state.tau - state.tau0) * (1.0 - p.xi) ** uses
        state = record_best(state, solutions, lengths)
        on_best = pheromone.edge_mask(state.best_solution[None], n)
        tau = jnp.where(on_best, (1.0 - p.rho) * tau + p.rho / state.best_cost, tau)
        return state.replace(tau=tau), {}
