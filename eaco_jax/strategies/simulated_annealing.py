"""Simulated annealing for continuous (constrained) problems: a population of independent chains.

S. Kirkpatrick, C. D. Gelatt, M. P. Vecchi, "Optimization by simulated annealing", Science
220 (1983) 671-680; the adaptive step of A. Corana, M. Marchesi, C. Martini, S. Ridella,
"Minimizing multimodal functions of continuous variables with the simulated annealing
algorithm", ACM TOMS 13 (1987) 262-280 (here a per-chain multiplicative rule).

Each ant is one Metropolis chain. A proposal moves every coordinate by a Gaussian of width
``step`` times the box width (clipped to the box); it is accepted when not worse, else with
probability exp(-Delta / T). The temperature falls geometrically from ``t0`` to ``t_final``
over ``anneal_iterations`` iterations, both relative to the spread (standard deviation) of
the first colony's objective values; each chain's step grows by ``step_up`` on acceptance and
shrinks by ``step_down`` on rejection (equilibrium acceptance about 24 % with the defaults).
Constraints: Delta is the difference of ``f + PEN v`` (penalty), or, for Deb / epsilon, of the
violation beyond epsilon scaled to objective units by the first colony's spreads when the
violations differ, else of the objective (:func:`continuous_base.energy_difference`).
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
class SAParams(cb.ConstraintParams):
    t0: Array = 0.1  # initial temperature, times the first colony's objective spread
    t_final: Array = 1e-6  # final temperature, same units
    anneal_iterations: Array = 1000.0  # iterations from t0 to t_final (then constant)
    step: Array = 0.1  # initial proposal width, fraction of the box width
    step_up: Array = 1.1  # step factor after an accepted move
    step_down: Array = 0.97  # step factor after a rejected move
    step_min: Array = 1e-9  # step bounds (fraction of the box width)
    step_max: Array = 0.5


@struct.dataclass
class SAState(cb.ConstrainedState):
    x: Array  # (m, n) current point of each chain
    f: Array
    v: Array
    step: Array  # (m,) proposal width per chain
    f_scale: Array  # objective spread of the first colony (temperature unit)
    v_scale: Array  # objective units per unit of violation (Deb / epsilon)
    uniform: Array  # (m,) the acceptance draws of the asked proposals (drawn in ask)


def _spread(a: Array) -> Array:
    finite = jnp.isfinite(a)
    n = jnp.maximum(finite.sum(), 1)
    mean = jnp.where(finite, a, 0.0).sum() / n
    var = jnp.where(finite, (a - mean) ** 2, 0.0).sum() / n
    return jnp.maximum(jnp.sqrt(var), 1e-12)


@dataclasses.dataclass(frozen=True)
class SimulatedAnnealing(Strategy):
    """``num_ants`` independent Metropolis chains with adaptive Gaussian steps."""

    num_ants: int = 40
    constraint_method: str = "epsilon"
    problem_kind: ClassVar[str] = "continuous"

    def __post_init__(self) -> None:
        ch.check_method(self.constraint_method)
        if self.num_ants < 1:
            raise ConfigError("SimulatedAnnealing needs num_ants >= 1")

    def default_params(self, problem: Any = None) -> SAParams:
        return as_params(SAParams())

    def prepare(self, problem: Any) -> Any:
        return cb.check_continuous(self, problem)

    def _init(self, key: Array, problem: Any, params: SAParams) -> SAState:
        dtype = problem.dtype
        params = as_params(params, dtype)
        k_x, k_run = jax.random.split(key)
        lo, hi = problem.lower, problem.upper
        m = self.num_ants
        x = lo + (hi - lo) * jax.random.uniform(k_x, (m, problem.dim), dtype)
        inf = jnp.full((m,), jnp.inf, dtype)
        one = jnp.ones((), dtype)
        return SAState(**cb.constrained_fields(k_run, params, problem), x=x, f=inf, v=inf,
                       step=jnp.full((m,), params.step, dtype), f_scale=one, v_scale=one,
                       uniform=jnp.zeros((m,), dtype))

    def _ask(self, key: Array, state: SAState, problem: Any) -> tuple[Array, SAState]:
        lo, hi = problem.lower, problem.upper
        k_move, k_accept = jax.random.split(key)
        noise = jax.random.normal(k_move, state.x.shape, state.x.dtype)
        x = jnp.clip(state.x + state.step[:, None] * (hi - lo) * noise, lo, hi)
        u = jax.random.uniform(k_accept, state.f.shape, state.f.dtype)
        return jnp.where(state.iteration == 0, state.x, x), state.replace(uniform=u)

    def temperature(self, state: SAState) -> Array:
        """T at this iteration (objective units)."""
        p = state.params
        frac = jnp.clip(state.iteration / jnp.maximum(p.anneal_iterations, 1.0), 0.0, 1.0)
        return state.f_scale * p.t0 * (p.t_final / p.t0) ** frac

    def _tell(self, state: SAState, solutions: Array, fitness: Evaluation,
              problem: Any) -> tuple[SAState, dict[str, Array]]:
        p = state.params
        f = fitness.f.astype(state.f.dtype)
        v = fitness.violation.astype(state.v.dtype)
        first = state.iteration == 0
        state, eps = cb.epsilon_level(state, v, p, self.constraint_method)
        f_scale = jnp.where(first, _spread(f), state.f_scale)
        v_scale = jnp.where(first, f_scale / _spread(v), state.v_scale)
        state = state.replace(f_scale=f_scale, v_scale=v_scale)
        delta = cb.energy_difference(f, v, state.f, state.v, self.constraint_method, eps, p,
                                     v_scale)
        t = self.temperature(state)
        accept = first | (delta <= 0) | (state.uniform < jnp.exp(-delta / t))
        step = jnp.clip(state.step * jnp.where(accept, p.step_up, p.step_down),
                        p.step_min, p.step_max)
        state = state.replace(
            x=jnp.where(accept[:, None], solutions, state.x).astype(state.x.dtype),
            f=jnp.where(accept, f, state.f), v=jnp.where(accept, v, state.v),
            step=jnp.where(first, state.step, step))
        state, metrics = cb.record(state, solutions, fitness, problem)
        return state, {**metrics, "temperature": t, "acceptance": jnp.mean(accept)}

    def scalar_cost(self, fitness: Evaluation) -> Array:
        return cb.feasible_cost(fitness)
