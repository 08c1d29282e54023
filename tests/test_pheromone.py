"""Each pheromone rule on a tiny hand-computed case (n = 4)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from eaco_jax.ops import pheromone as ph

T1 = jnp.array([[0, 1, 2, 3]], jnp.int32)  # edges 01 12 23 30
T2 = jnp.array([[0, 2, 1, 3]], jnp.int32)  # edges 02 21 13 30
TAU = jnp.full((4, 4), 0.5, jnp.float32)


def _sym(pairs, value, n=4):
    m = np.zeros((n, n))
    for i, j in pairs:
        m[i, j] += value
        m[j, i] += value
    return m


def test_edge_sum_and_mask():
    tours = jnp.concatenate([T1, T2])
    got = np.asarray(ph.edge_sum(tours, jnp.array([1.0, 10.0]), 4))
    want = _sym([(0, 1), (1, 2), (2, 3), (3, 0)], 1.0) + _sym([(0, 2), (2, 1), (1, 3), (3, 0)], 10)
    np.testing.assert_allclose(got, want)
    assert np.array_equal(np.asarray(ph.edge_mask(T1, 4)), want * 0 + _sym(
        [(0, 1), (1, 2), (2, 3), (3, 0)], 1) > 0)


def test_local_update_eq68_70():
    # two ants: L = 10 and 20, Q = 2, rho = 0.1. Edge 30 used by both, 01 by ant 1 only.
    tours = jnp.concatenate([T1, T2])
    tau = ph.local_update(TAU, tours, jnp.array([10.0, 20.0]), 0.1, 2.0)
    tau = np.asarray(tau)
    np.testing.assert_allclose(tau[3, 0], 0.9 * 0.5 + 0.1 * (2 / 10 + 2 / 20))
    np.testing.assert_allclose(tau[0, 1], 0.9 * 0.5 + 0.1 * (2 / 10))
    np.testing.assert_allclose(tau[0, 2], 0.9 * 0.5 + 0.1 * (2 / 20))
    # every edge of K4 is used here except none: check an unused edge on a single ant
    single = np.asarray(ph.local_update(TAU, T1, jnp.array([10.0]), 0.1, 2.0))
    assert single[0, 2] == 0.5  # not on the tour: untouched (local rule)
    np.testing.assert_allclose(single, single.T)


def test_global_update_eq71():
    tau = np.asarray(ph.global_update(TAU, T1[0], jnp.float32(8.0), 0.25))
    on = 0.75 * 0.5 + 0.25 / 8.0
    off = 0.75 * 0.5
    assert np.isclose(tau[0, 1], on) and np.isclose(tau[1, 0], on) and np.isclose(tau[3, 0], on)
    assert np.isclose(tau[0, 2], off) and np.isclose(tau[1, 3], off)


def test_elitist_update_eq73_74():
    # ants T1 (L=10, w=1) and T2 (L=20, w=0), best = T2 with L=20, sigma=3, Q=2, rho=0.5
    tours = jnp.concatenate([T1, T2])
    tau = np.asarray(ph.elitist_update(
        TAU, tours, jnp.array([10.0, 20.0]), jnp.array([1.0, 0.0]), T2[0], jnp.float32(20.0),
        0.5, 2.0, 3.0))
    # edge 01: on T1 only -> 0.5*0.5 + 0.5*(2/10)
    np.testing.assert_allclose(tau[0, 1], 0.25 + 0.5 * 0.2, rtol=1e-6)
    # edge 02: on best only -> 0.25 + 0.5*(3*2/20)
    np.testing.assert_allclose(tau[0, 2], 0.25 + 0.5 * 0.3, rtol=1e-6)
    # edge 30: on both -> 0.25 + 0.5*(0.2 + 0.3)
    np.testing.assert_allclose(tau[3, 0], 0.25 + 0.5 * 0.5, rtol=1e-6)


def test_elitist_deposit_condition_eq3_4():
    lengths = jnp.array([10.0, 12.0, 20.0, 30.0])  # mean 18
    np.testing.assert_array_equal(ph.elitist_deposit_mask(lengths, 11.0), [1, 1, 0, 0])
    np.testing.assert_array_equal(ph.elitist_deposit_mask(lengths, 10.0), [0, 0, 0, 0])


def test_adaptive_weight_eq5():
    np.testing.assert_allclose(ph.adaptive_weight(10.0, 15.0), (1 / 10) / (1 / 10 + 1 / 15))
    np.testing.assert_allclose(ph.adaptive_weight(10.0, 15.0), 0.6, rtol=1e-6)
    np.testing.assert_allclose(ph.adaptive_weight(7.0, 7.0), 0.5)


def test_mmas_bounds_clamp_and_tau0():
    tmax, tmin = ph.mmas_bounds(jnp.float32(100.0), 50, jnp.float32(0.05))
    root = 0.05 ** (1 / 50)
    np.testing.assert_allclose(tmax, 0.01)
    np.testing.assert_allclose(tmin, 0.01 * (1 - root) / (24 * root), rtol=1e-5)
    tau = ph.clamp(jnp.array([0.0, 0.005, 1.0]), tmin, tmax)
    np.testing.assert_allclose(tau, [tmin, 0.005, 0.01], rtol=1e-6)
    np.testing.assert_allclose(ph.initial_tau(50, 400.0), 1 / (50 * 400))


def test_evaporation_schedule_and_reset():
    assert np.isclose(ph.evaporation_schedule(0.2, 0.0, 50.0, 0.5), 0.2)
    assert np.isclose(ph.evaporation_schedule(0.2, 25.0, 50.0, 0.5), 0.15)
    assert np.isclose(ph.evaporation_schedule(0.2, 500.0, 50.0, 0.5), 0.1)
    assert np.all(ph.reset(TAU, 2.0, jnp.bool_(True)) == 2.0)
    assert np.all(ph.reset(TAU, 2.0, jnp.bool_(False)) == 0.5)


def test_mmas_bounds_with_candidate_branching():
    """ACOTSP on candidate lists: tau_min assumes (nn_ants + 1) / 2 choices, not n / 2 - 1."""
    tmax, tmin = ph.mmas_bounds(jnp.float32(100.0), 50, jnp.float32(0.05), avg=10.0)
    root = 0.05 ** (1 / 50)
    np.testing.assert_allclose(tmin, 0.01 * (1 - root) / (10 * root), rtol=1e-5)


def test_lambda_branching_factor():
    """1 for converged trails (two strong candidate edges per node); ACOTSP's formula on
    random trails."""
    rng = np.random.default_rng(0)
    n, k = 12, 5
    tour = rng.permutation(n)
    cands = np.stack([_cands(tour, i, k, rng) for i in range(n)])
    tau = np.full((n, n), 0.01) + ph.edge_sum(jnp.asarray(tour[None]), jnp.ones(1), n) * 0.5
    assert float(ph.branching_factor(jnp.asarray(tau, jnp.float32), jnp.asarray(cands))) == 1.0
    tau = rng.random((n, n)).astype(np.float32)
    t = np.take_along_axis(tau, cands, axis=1)
    lo, hi = t.min(1, keepdims=True), t.max(1, keepdims=True)
    want = (t > lo + 0.05 * (hi - lo)).sum() / (2 * n)
    got = float(ph.branching_factor(jnp.asarray(tau), jnp.asarray(cands)))
    np.testing.assert_allclose(got, want, rtol=1e-6)


def _cands(tour, i, k, rng):
    """k candidates of node i: its two tour neighbours first, then other nodes."""
    pos = int(np.flatnonzero(tour == i)[0])
    nb = [tour[(pos + 1) % len(tour)], tour[pos - 1]]
    rest = rng.permutation(np.setdiff1d(np.arange(len(tour)), nb + [i]))
    return np.r_[nb, rest[: k - 2]].astype(np.int32)
