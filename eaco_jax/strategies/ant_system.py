"""Ant system (AS) and elitist ant system (EAS) on a construction graph.

M. Dorigo, V. Maniezzo, A. Colorni, "Ant system: optimization by a colony of cooperating
agents", IEEE Trans. SMC-B 26 (1996) 29-41; parameters as in M. Dorigo, T. Stuetzle, "Ant
Colony Optimization", MIT Press 2004, Box 3.1 / Table 3.6 (alpha = 1, beta = 2..5, rho = 0.5,
m = n, tau0 = m / L_nn; EAS: e = n elitist ants).

Every ant builds a tour by Eq. 2 (no q0 rule), then all trails evaporate and every ant deposits
1/L_k on its edges, plus ``elitist_weight`` / L_bs on the best-so-far tour (EAS; 0 = AS):

    tau <- (1 - rho) tau + sum_k [e in T_k] / L_k + e [e in T_bs] / L_bs

No bounds, no restarts. This is the paper's Eq. 73-74 without the deposit condition and the
adaptive weight, in Dorigo's original units (GraphEACO scales every deposit by rho, see
:mod:`eaco_jax.ops.pheromone`; the dynamics are the same up to that factor and tau0).
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
class ASParams:
    alpha: Array = 1.0
    beta: Array = 2.0
    rho: Array = 0.5
    elitist_weight: Array = 0.0  # e: 0 = AS, n = EAS (Dorigo & Stuetzle 2004)


@struct.dataclass
class ASState(State):
    tau: Array


@dataclasses.dataclass(frozen=True)
class AntSystem(Strategy):
    """AS colony; ``elitist=True`` is EAS (default ``elitist_weight`` = n)."""

    num_ants: int = 40
    elitist: bool = False
    local_search: str = "none"
    candidate_lists: bool = True
    problem_kind: ClassVar[str] = "graph"

    def __post_init__(self) -> None:
        tb.check_local_search(self.local_search)
        if self.num_ants < 1:
            raise ConfigError("AntSystem needs num_ants >= 1")

    def default_params(self, problem: Any = None) -> ASParams:
        n = getattr(getattr(problem, "dist", None), "shape", (0,))[0]
        if self.elitist and not n:
            raise ConfigError("AntSystem(elitist=True).default_params needs the problem (e = n)")
        return as_params(ASParams(elitist_weight=float(n) if self.elitist else 0.0))

    def prepare(self, problem: Any) -> Any:
        return tb.check_graph(self, problem)

    def _init(self, key: Array, problem: Any, params: ASParams) -> ASState:
        n = problem.dist.shape[0]
        tau0 = self.num_ants / tb.nearest_neighbour_length(problem)
        return ASState(**base_fields(key, as_params(params), jnp.arange(n, dtype=jnp.int32)),
                       tau=jnp.full((n, n), tau0, jnp.float32))

    def _ask(self, key: Array, state: ASState, problem: Any) -> tuple[Array, ASState]:
        p = state.params
        tours = tb.build(key, state.tau, problem, self.num_ants, p.alpha, p.beta,
                         candidate_lists=self.candidate_lists)
        return tb.improve(tours, problem, self.local_search), state

    def _tell(self, state: ASState, solutions: Array, fitness: Array,
              problem: Any) -> tuple[ASState, dict[str, Array]]:
        p = state.params
        n = state.tau.shape[0]
        lengths = fitness.astype(jnp.float32)
        state = record_best(state, solutions, lengths)
        deposit = pheromone.edge_sum(solutions, 1.0 / lengths, n)
        elite = pheromone.edge_sum(state.best_solution[None],
                                   (p.elitist_weight / state.best_cost)[None], n)
        tau = (1.0 - p.rho) * state.tau + deposit + elite
        tau = jnp.maximum(tau, 1e-30)  # keep log(tau) finite after long evaporation
        return state.replace(tau=tau), {}
