"""2-opt local search: permutations, never longer, fixed points, candidate lists, jit/vmap."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.ops.local_search import two_opt
from eaco_jax.problems import TSP, load_tsplib


def _random_tours(n: int, m: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32)


def _is_2opt_optimal(d: np.ndarray, tour: np.ndarray) -> bool:
    """Brute force over all pairs of non-adjacent edges."""
    n = len(tour)
    t = np.asarray(tour)
    a, b = t, np.roll(t, -1)
    e = d[a, b]
    gain = e[:, None] + e[None, :] - d[a[:, None], a[None, :]] - d[b[:, None], b[None, :]]
    i, j = np.triu_indices(n, 2)
    keep = ~((i == 0) & (j == n - 1))
    return bool(np.all(gain[i[keep], j[keep]] <= 0))


@pytest.fixture(scope="module")
def eil51():
    return load_tsplib("eil51", neighbors=10)


def test_permutation_never_longer_and_locally_optimal_full(eil51):
    tours = _random_tours(51, 4)
    out = np.asarray(two_opt(tours, eil51.dist))
    d = np.asarray(eil51.dist)
    for t in out:
        assert sorted(t) == list(range(51))
    before, after = eil51.evaluate(tours), eil51.evaluate(out)
    assert np.all(after <= before) and np.all(after < before)
    # the full neighbourhood search ends in a true 2-opt local optimum
    assert all(_is_2opt_optimal(d, t) for t in out)
    assert float(after.mean()) < 1.15 * eil51.optimum


def test_candidate_lists_close_to_full_quality(eil51):
    tours = _random_tours(51, 4, seed=1)
    full = eil51.evaluate(two_opt(tours, eil51.dist))
    cand = eil51.evaluate(two_opt(tours, eil51.dist, eil51.neighbors))
    assert np.all(np.asarray(cand) <= np.asarray(eil51.evaluate(tours)))
    # candidate lists of 10 neighbours lose at most a few percent on average
    assert float(cand.mean()) <= 1.05 * float(full.mean())


def test_optimal_and_local_optimal_tours_are_unchanged(eil51):
    opt = (
        np.array(
            [
                1,
                22,
                8,
                26,
                31,
                28,
                3,
                36,
                35,
                20,
                2,
                29,
                21,
                16,
                50,
                34,
                30,
                9,
                49,
                10,
                39,
                33,
                45,
                15,
                44,
                42,
                40,
                19,
                41,
                13,
                25,
                14,
                24,
                43,
                7,
                23,
                48,
                6,
                27,
                51,
                46,
                12,
                47,
                18,
                4,
                17,
                37,
                5,
                38,
                11,
                32,
            ],
            np.int32,
        )
        - 1
    )
    batch = np.repeat(opt[None], 4, axis=0)
    out, moves = two_opt(batch, eil51.dist, eil51.neighbors, return_moves=True)
    np.testing.assert_array_equal(out, batch)
    assert np.all(np.asarray(moves) == 0)
    local = two_opt(_random_tours(51, 4, seed=2), eil51.dist)
    np.testing.assert_array_equal(two_opt(local, eil51.dist), local)


def test_one_crossing_is_fixed():
    # points on a circle; the identity order is optimal, reversing a middle segment's interior
    # (swapping two cities' order) introduces a crossing 2-opt must undo
    n = 12
    ang = 2 * np.pi * np.arange(n) / n
    p = TSP.from_coords(np.c_[1000 * np.cos(ang), 1000 * np.sin(ang)], neighbors=4)
    crossed = np.arange(n, dtype=np.int32)
    crossed[3:8] = crossed[3:8][::-1]
    assert float(p.evaluate(crossed[None])[0]) > float(p.evaluate(np.arange(n)[None])[0])
    for nbr in (None, p.neighbors):
        out = np.asarray(two_opt(crossed[None], p.dist, nbr))[0]
        assert float(p.evaluate(out[None])[0]) == float(p.evaluate(np.arange(n)[None])[0])


def test_jit_vmap_and_batch_consistency(eil51):
    tours = _random_tours(51, 4, seed=3)
    batch = np.asarray(two_opt(tours, eil51.dist, eil51.neighbors))
    singles = np.stack(
        [np.asarray(two_opt(t[None], eil51.dist, eil51.neighbors))[0] for t in tours]
    )
    np.testing.assert_array_equal(batch, singles)
    f = jax.jit(lambda prob, t: two_opt(t, prob.dist, prob.neighbors))
    np.testing.assert_array_equal(f(eil51, tours), batch)
    vm = jax.vmap(lambda t: two_opt(t, eil51.dist, eil51.neighbors))(tours.reshape(2, 2, 51))
    np.testing.assert_array_equal(np.asarray(vm).reshape(4, 51), batch)


def test_max_moves_and_moves_per_step(eil51):
    tours = _random_tours(51, 4, seed=4)
    capped, moves = two_opt(tours, eil51.dist, eil51.neighbors, max_moves=2, return_moves=True)
    assert np.all(np.asarray(moves) <= 2)
    assert np.all(eil51.evaluate(capped) < eil51.evaluate(tours))
    one = eil51.evaluate(two_opt(tours, eil51.dist, eil51.neighbors, moves_per_step=1))
    many = eil51.evaluate(two_opt(tours, eil51.dist, eil51.neighbors))
    assert np.all(one < eil51.evaluate(tours))
    assert abs(float(one.mean()) - float(many.mean())) < 0.05 * float(one.mean())


def test_bad_shapes_raise_clear_errors(eil51):
    with pytest.raises(ValueError, match=r"shape \(m, n\)"):
        two_opt(jnp.arange(51), eil51.dist)
    with pytest.raises(ValueError, match="dist must have shape"):
        two_opt(jnp.zeros((2, 50), jnp.int32), eil51.dist)
    with pytest.raises(ValueError, match="neighbors must have shape"):
        two_opt(_random_tours(51, 1), eil51.dist, eil51.neighbors[:10])
