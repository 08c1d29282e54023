"""Tabu search for continuous (constrained) problems: moves in concentric boxes, tabu regions.

F. Glover, "Tabu search - Part I", ORSA Journal on Computing 1 (1989) 190-206; continuous
moves after R. Chelouah, P. Siarry, "Tabu search applied to global optimization", EJOR 123
(2000) 256-270 (ECTS: neighbours in concentric hyper-rectangles around the current point, a
tabu list of balls around recent points, the neighbourhood shrunk when the search stalls).

One searcher per state. Each iteration ``num_ants`` neighbours of the current point ``c`` are
asked: neighbour ``k`` lies in ring ``r = k mod rings + 1``, ``c + radius * r / rings * u``
with ``u`` uniform in [-1, 1]^n (times the box width). A neighbour inside the box of half-width
``tabu_radius`` around any of the last ``tenure`` current points is tabu (``tries`` draws are
made per neighbour and the first non-tabu one kept). ``tell`` moves to the best non-tabu
neighbour, even when it is worse than ``c`` (a tabu neighbour is allowed when it beats the
best so far: aspiration), and puts the old ``c`` on the tabu list. After ``shrink_after``
iterations without a new best, ``radius`` is multiplied by ``shrink`` (down to ``radius_min``).
Comparisons use ContinuousEACO's constraint handling (epsilon / Deb / penalty).
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
class TabuParams(cb.ConstraintParams):
    radius: Array = 0.2  # outer neighbourhood half-width, fraction of the box width
    tabu_radius: Array = 0.01  # tabu box half-width around recent points, same units
    shrink: Array = 0.5  # radius factor when the search stalls
    shrink_after: Array = 20.0  # iterations without a new best before shrinking
    radius_min: Array = 1e-9


@struct.dataclass
class TabuState(cb.ConstrainedState):
    current: Array  # (n,) the current point
    current_f: Array
    current_v: Array
    tabu: Array  # (tenure, n) recent current points (circular buffer; unused rows are nan)
    slot: Array  # next slot of the buffer
    radius: Array
    since_shrink: Array
    asked_tabu: Array  # (m,) which asked neighbours were tabu


@dataclasses.dataclass(frozen=True)
class TabuSearch(Strategy):
    """ECTS-style continuous tabu search with ``num_ants`` neighbours per iteration."""

    num_ants: int = 40
    rings: int = 4
    tenure: int = 10
    tries: int = 4
    constraint_method: str = "epsilon"
    problem_kind: ClassVar[str] = "continuous"

    def __post_init__(self) -> None:
        ch.check_method(self.constraint_method)
        if min(self.num_ants, self.rings, self.tenure, self.tries) < 1:
            raise ConfigError("TabuSearch needs num_ants, rings, tenure and tries >= 1")

    def default_params(self, problem: Any = None) -> TabuParams:
        return as_params(TabuParams())

    def prepare(self, problem: Any) -> Any:
        return cb.check_continuous(self, problem)

    def _init(self, key: Array, problem: Any, params: TabuParams) -> TabuState:
        dtype = problem.dtype
        params = as_params(params, dtype)
        k_x, k_run = jax.random.split(key)
        lo, hi = problem.lower, problem.upper
        c = lo + (hi - lo) * jax.random.uniform(k_x, (problem.dim,), dtype)
        return TabuState(
            **cb.constrained_fields(k_run, params, problem), current=c,
            current_f=jnp.asarray(jnp.inf, dtype), current_v=jnp.asarray(jnp.inf, dtype),
            tabu=jnp.full((self.tenure, problem.dim), jnp.nan, dtype),
            slot=jnp.zeros((), jnp.int32), radius=params.radius,
            since_shrink=jnp.zeros((), jnp.int32),
            asked_tabu=jnp.zeros((self.num_ants,), bool))

    def is_tabu(self, state: TabuState, x: Array, problem: Any) -> Array:
        """(..., ) True where a point lies in a tabu box (NaN rows never match)."""
        width = state.params.tabu_radius * (problem.upper - problem.lower)
        close = jnp.abs(x[..., None, :] - state.tabu) <= width
        return jnp.any(jnp.all(close, axis=-1), axis=-1)

    def _ask(self, key: Array, state: TabuState, problem: Any) -> tuple[Array, TabuState]:
        lo, hi = problem.lower, problem.upper
        m, n = self.num_ants, problem.dim
        ring = (jnp.arange(m) % self.rings + 1) / self.rings
        u = jax.random.uniform(key, (self.tries, m, n), state.current.dtype, -1.0, 1.0)
        half = (state.radius * ring)[None, :, None] * (hi - lo)
        cand = jnp.clip(state.current + half * u, lo, hi)  # (tries, m, n)
        tabu = self.is_tabu(state, cand, problem)  # (tries, m)
        pick = jnp.where(jnp.any(~tabu, axis=0), jnp.argmin(tabu, axis=0), self.tries - 1)
        x = jnp.take_along_axis(cand, pick[None, :, None], axis=0)[0]
        flags = jnp.take_along_axis(tabu, pick[None, :], axis=0)[0]
        first = state.iteration == 0  # the first colony: the start point and its neighbours
        x = jnp.where(first, x.at[0].set(state.current), x)
        return x, state.replace(asked_tabu=flags & ~first)

    def _tell(self, state: TabuState, solutions: Array, fitness: Evaluation,
              problem: Any) -> tuple[TabuState, dict[str, Array]]:
        p = state.params
        f = fitness.f.astype(state.current_f.dtype)
        v = fitness.violation.astype(state.current_v.dtype)
        state, eps = cb.epsilon_level(state, v, p, self.constraint_method)
        method = self.constraint_method
        aspire = cb.better(f, v, state.best_f, state.best_violation, method, eps, p)
        allowed = ~state.asked_tabu | aspire
        key_f = jnp.where(allowed, f, jnp.inf)
        key_v = jnp.where(allowed, v, jnp.inf)
        i = ch.rank_order(key_f, key_v, method, eps, p.penalty)[0]
        move = allowed[i]
        tabu = jnp.where(move & jnp.isfinite(state.current_f),
                         state.tabu.at[state.slot].set(state.current), state.tabu)
        slot = jnp.where(move & jnp.isfinite(state.current_f), (state.slot + 1) % self.tenure,
                         state.slot)
        previous_best = (state.best_f, state.best_violation)
        state = state.replace(
            current=jnp.where(move, solutions[i], state.current).astype(state.current.dtype),
            current_f=jnp.where(move, f[i], state.current_f),
            current_v=jnp.where(move, v[i], state.current_v), tabu=tabu, slot=slot)
        state, metrics = cb.record(state, solutions, fitness, problem)
        improved = ch.better(state.best_f, state.best_violation, *previous_best, "deb")
        since = jnp.where(improved, 0, state.since_shrink + 1)
        shrink = since >= p.shrink_after
        state = state.replace(
            radius=jnp.where(shrink, jnp.maximum(state.radius * p.shrink, p.radius_min),
                             state.radius),
            since_shrink=jnp.where(shrink, 0, since))
        return state, {**metrics, "radius": state.radius}

    def scalar_cost(self, fitness: Evaluation) -> Array:
        return cb.feasible_cost(fitness)
