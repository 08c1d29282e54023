"""Real-coded genetic operators of Deep & Thakur (2007): Laplace crossover and power mutation.

* K. Deep, M. Thakur, "A new crossover operator for real coded genetic algorithms",
  Applied Mathematics and Computation 188 (2007) 895-911 (Laplace crossover, LX).
* K. Deep, M. Thakur, "A new mutation operator for real coded genetic algorithms",
  Applied Mathematics and Computation 193 (2007) 211-230 (power mutation, PM).

These are the operators of the paper's real-coded GA ("LX-PM"); EACO applies them to ants.
Both functions take their uniform draws as arguments (``u``, ``s1``, ``r``) so a test can
compare them with the published formulas on fixed numbers; the ``*_sample`` wrappers draw them.
Offspring are clipped to the box (the papers leave out-of-box handling open; clipping keeps the
bounds exact and puts mass on them, where many constrained optima lie).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def laplace_beta(u: Array, a: Array, b: Array) -> Array:
    """Laplace-distributed beta: a - b ln(u) if u <= 1/2, else a + b ln(u)  (Deep & Thakur, LX)."""
    u = jnp.clip(u, jnp.finfo(jnp.asarray(u).dtype).tiny, 1.0)
    return jnp.where(u <= 0.5, a - b * jnp.log(u), a + b * jnp.log(u))


def laplace_crossover(x1: Array, x2: Array, u: Array, a: Array = 0.0,
                      b: Array = 0.15) -> tuple[Array, Array]:
    """LX offspring y1 = x1 + beta |x1 - x2|, y2 = x2 + beta |x1 - x2| (beta per coordinate)."""
    beta = laplace_beta(u, a, b)
    d = jnp.abs(x1 - x2)
    return x1 + beta * d, x2 + beta * d


def power_mutation(x: Array, lower: Array, upper: Array, s1: Array, r: Array,
                   p: Array = 10.0) -> Array:
    """PM: s = s1^p, t = (x - l)/(u - l); x - s (x - l) if t < r else x + s (u - x)."""
    s = s1**p
    t = (x - lower) / jnp.where(upper > lower, upper - lower, 1.0)
    return jnp.where(t < r, x - s * (x - lower), x + s * (upper - x))


def laplace_crossover_sample(key: Array, x1: Array, x2: Array, lower: Array, upper: Array,
                             a: Array = 0.0, b: Array = 0.15) -> tuple[Array, Array]:
    """LX with fresh uniform draws, offspring clipped to [lower, upper]."""
    u = jax.random.uniform(key, x1.shape, x1.dtype)
    y1, y2 = laplace_crossover(x1, x2, u, a, b)
    return jnp.clip(y1, lower, upper), jnp.clip(y2, lower, upper)


def power_mutation_sample(key: Array, x: Array, lower: Array, upper: Array,
                          p: Array = 10.0) -> Array:
    """PM with fresh draws; the result stays in [lower, upper] by construction (clipped too)."""
    k1, k2 = jax.random.split(key)
    s1 = jax.random.uniform(k1, x.shape, x.dtype)
    r = jax.random.uniform(k2, x.shape, x.dtype)
    return jnp.clip(power_mutation(x, lower, upper, s1, r, p), lower, upper)
