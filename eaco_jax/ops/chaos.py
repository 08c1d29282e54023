"""Logistic-map chaos: the deterministic chaotic sequence that perturbs node selection.

The paper's "chaos perturbation" of the selection rule (§ Adaptive control) uses the logistic
map x <- 4x(1-x) on (0, 1). In float32 the map can fall onto its absorbing point 0 (from 0.5 or
1.0) or the fixed point 0.75; we clip to [eps, 1-eps] and nudge 0.75 so the sequence keeps moving.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array

_EPS = 1e-4


def logistic_init(key: Array, shape: tuple[int, ...]) -> Array:
    """Random start values in (eps, 1-eps), away from the map's fixed points."""
    return jax.random.uniform(key, shape, jnp.float32, minval=0.01, maxval=0.99)


def logistic_step(x: Array) -> Array:
    """One step of x <- 4x(1-x), kept inside (0, 1) and off the fixed point 3/4."""
    x = 4.0 * x * (1.0 - x)
    x = jnp.where(jnp.abs(x - 0.75) < 1e-6, 0.7501, x)
    return jnp.clip(x, _EPS, 1.0 - _EPS)


def perturbation(x: Array, strength: Array) -> Array:
    """Multiplicative selection factor 1 + strength * (2x - 1), in [1 - strength, 1 + strength]."""
    return 1.0 + strength * (2.0 * x - 1.0)
