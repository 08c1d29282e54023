"""Particle swarm optimisation (global-best topology, constriction coefficients).

J. Kennedy, R. Eberhart, "Particle swarm optimization", Proc. ICNN 1995; the constriction
(inertia 0.7298, c1 = c2 = 1.49618) of M. Clerc, J. Kennedy, "The particle swarm - explosion,
stability, and convergence in a multidimensional complex space", IEEE TEC 6 (2002) 58-73.

One particle per ant: ``v <- w v + c1 r1 (p - x) + c2 r2 (g - x)``, ``x <- x + v``, with
``|v|`` clamped to ``v_max`` times the box width and ``x`` clipped to the box (the velocity
component that left the box is zeroed). Personal bests ``p`` and the swarm best ``g`` are
compared with the same constraint handling as ContinuousEACO (``constraint_method``:
epsilon / Deb / penalty, :mod:`eaco_jax.strategies.continuous_base`). The first ``ask``
returns the uniformly drawn initial swarm; nothing is evaluated in ``init``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ConfigError
from eaco_jax.ops import constraints as ch
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies import continuous_base as cb
from eaco_jax.strategies.base import Strategy, as_params

Array = jax.Array


@struct.dataclass
class PSOParams(cb.ConstraintParams):
    inertia: Array = 0.7298  # w
    c1: Array = 1.49618  # cognitive weight
    c2: Array = 1.49618  # social weight
    v_max: Array = 0.5  # velocity clamp, fraction of the box width


@struct.dataclass
class PSOState(cb.ConstrainedState):
    x: Array  # (m, n) positions (the last asked swarm)
    velocity: Array
    pbest_x: Array
    pbest_f: Array
    pbest_v: Array


@dataclasses.dataclass(frozen=True)
class PSO(Strategy):
    """Global-best PSO with constriction, for continuous (constrained) problems."""

    num_ants: int = 40
    constraint_method: str = "epsilon"
    problem_kind: ClassVar[str] = "continuous"

    def __post_init__(self) -> None:
        ch.check_method(self.constraint_method)
        if self.num_ants < 2:
            raise ConfigError("PSO needs num_ants >= 2")

    def default_params(self, problem: Any = None) -> PSOParams:
        return as_params(PSOParams())

    def prepare(self, problem: Any) -> Any:
        return cb.check_continuous(self, problem)

    def _init(self, key: Array, problem: Any, params: PSOParams) -> PSOState:
        dtype = problem.dtype
        params = as_params(params, dtype)
        k_x, k_v, k_run = jax.random.split(key, 3)
        lo, hi = problem.lower, problem.upper
        m, n = self.num_ants, problem.dim
        x = lo + (hi - lo) * jax.random.uniform(k_x, (m, n), dtype)
        v = (hi - lo) * params.v_max * jax.random.uniform(k_v, (m, n), dtype, -1.0, 1.0)
        inf = jnp.full((m,), jnp.inf, dtype)
        return PSOState(**cb.constrained_fields(k_run, params, problem), x=x, velocity=v,
                        pbest_x=x, pbest_f=inf, pbest_v=inf)

    def _ask(self, key: Array, state: PSOState, problem: Any) -> tuple[Array, PSOState]:
        p = state.params
        lo, hi = problem.lower, problem.upper
        m, n = state.x.shape
        k1, k2 = jax.random.split(key)
        g = state.pbest_x[ch.rank_order(state.pbest_f, state.pbest_v, self.constraint_method,
                                        state.epsilon, p.penalty)[0]]
        r1 = jax.random.uniform(k1, (m, n), state.x.dtype)
        r2 = jax.random.uniform(k2, (m, n), state.x.dtype)
        v = (p.inertia * state.velocity + p.c1 * r1 * (state.pbest_x - state.x)
             + p.c2 * r2 * (g[None, :] - state.x))
        vmax = p.v_max * (hi - lo)
        v = jnp.clip(v, -vmax, vmax)
        moved = state.x + v
        x = jnp.clip(moved, lo, hi)
        v = jnp.where(moved == x, v, 0.0)
        first = state.iteration == 0  # the initial swarm is evaluated before it moves
        x = jnp.where(first, state.x, x)
        v = jnp.where(first, state.velocity, v)
        return x, state.replace(x=x, velocity=v)

    def _tell(self, state: PSOState, solutions: Array, fitness: Evaluation,
              problem: Any) -> tuple[PSOState, dict[str, Array]]:
        p = state.params
        f = fitness.f.astype(state.pbest_f.dtype)
        v = fitness.violation.astype(state.pbest_v.dtype)
        state, eps = cb.epsilon_level(state, v, p, self.constraint_method)
        better = cb.better(f, v, state.pbest_f, state.pbest_v, self.constraint_method, eps, p)
        state = state.replace(
            x=solutions.astype(state.x.dtype),
            pbest_x=jnp.where(better[:, None], solutions, state.pbest_x),
            pbest_f=jnp.where(better, f, state.pbest_f),
            pbest_v=jnp.where(better, v, state.pbest_v),
        )
        return cb.record(state, solutions, fitness, problem)

    def scalar_cost(self, fitness: Evaluation) -> Array:
        return cb.feasible_cost(fitness)
