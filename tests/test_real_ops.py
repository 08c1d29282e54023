"""Laplace crossover and power mutation against their published formulas (Deep & Thakur 2007)."""

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.ops.real_ops import (
    laplace_crossover,
    laplace_crossover_sample,
    power_mutation,
    power_mutation_sample,
)


def test_laplace_crossover_matches_formula():
    rng = np.random.default_rng(0)
    x1, x2 = rng.uniform(-5, 5, (2, 50))
    u = rng.uniform(0, 1, 50)
    a, b = 0.0, 0.35
    # the formula, written out: beta = a - b ln u (u <= 1/2), a + b ln u (u > 1/2)
    beta = np.array([a - b * np.log(ui) if ui <= 0.5 else a + b * np.log(ui) for ui in u])
    want1 = x1 + beta * np.abs(x1 - x2)
    want2 = x2 + beta * np.abs(x1 - x2)
    y1, y2 = laplace_crossover(jnp.asarray(x1), jnp.asarray(x2), jnp.asarray(u), a, b)
    np.testing.assert_allclose(np.asarray(y1), want1, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(np.asarray(y2), want2, rtol=1e-5, atol=1e-5)


def test_power_mutation_matches_formula():
    rng = np.random.default_rng(1)
    lo, hi = -2.0, 3.0
    x = rng.uniform(lo, hi, 200)
    s1, r = rng.uniform(0, 1, (2, 200))
    p = 10.0
    s = s1**p
    t = (x - lo) / (hi - lo)
    want = np.where(t < r, x - s * (x - lo), x + s * (hi - x))
    got = power_mutation(jnp.asarray(x), lo, hi, jnp.asarray(s1), jnp.asarray(r), p)
    np.testing.assert_allclose(np.asarray(got), want, rtol=1e-5, atol=1e-5)
    # it moves towards the lower bound exactly when t < r
    moved_down = np.asarray(got) <= x + 1e-5
    np.testing.assert_array_equal(moved_down[t < r], True)


def test_operators_keep_bounds():
    lo = jnp.array([-1.0, 0.0, 10.0, -5.0])
    hi = jnp.array([1.0, 0.5, 20.0, 5.0])
    keys = jax.random.split(jax.random.key(0), 3)
    x = lo + (hi - lo) * jax.random.uniform(keys[0], (500, 4))
    y = lo + (hi - lo) * jax.random.uniform(keys[1], (500, 4))
    ks = jax.random.split(keys[2], 500)
    c1, c2 = jax.vmap(lambda k, a, b: laplace_crossover_sample(k, a, b, lo, hi, 0.0, 5.0))(ks, x, y)
    m = jax.vmap(lambda k, a: power_mutation_sample(k, a, lo, hi, 0.5))(ks, x)
    for arr in (c1, c2, m):
        assert bool(jnp.all((arr >= lo) & (arr <= hi)))
