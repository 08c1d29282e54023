"""Edge diversity of a colony: identical / reversed tours score 0, unrelated tours near 1."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from eaco_jax.ops.diversity import edge_diversity


def _edges(t) -> set[frozenset[int]]:
    """Undirected edges of a closed tour."""
    return {frozenset((int(t[i]), int(t[(i + 1) % len(t)]))) for i in range(len(t))}


def shared_edges(tours) -> np.ndarray:
    """(m, m) brute-force table: undirected edges each pair of tours has in common."""
    sets = [_edges(t) for t in tours]
    return np.array([[len(a & b) for b in sets] for a in sets])


def test_identical_and_reversed_and_rotated_tours_have_zero_diversity():
    rng = np.random.default_rng(0)
    t = rng.permutation(30).astype(np.int32)
    colony = np.stack([t, t[::-1], np.roll(t, 7), np.roll(t[::-1], 3)])
    assert float(edge_diversity(colony)) == 0.0
    assert np.all(shared_edges(colony) == 30)


def test_unrelated_tours_are_diverse_and_bounds():
    rng = np.random.default_rng(1)
    colony = np.stack([rng.permutation(200) for _ in range(6)]).astype(np.int32)
    d = float(edge_diversity(colony))
    assert 0.95 < d <= 1.0  # random tours share ~2 edges of 200
    # two tours with no common edge at all: distance exactly 1
    n = 7
    a = np.arange(n)
    b = (2 * np.arange(n)) % n  # steps of 2 on a 7-cycle: no edge of a
    assert float(edge_diversity(np.stack([a, b]))) == 1.0
    assert float(edge_diversity(a[None])) == 0.0


def test_matches_brute_force_and_jits():
    rng = np.random.default_rng(2)
    colony = np.stack([rng.permutation(12) for _ in range(5)]).astype(np.int32)
    colony[1] = colony[0]
    colony[2, 3:6] = colony[2, 3:6][::-1]

    pairs = [
        1 - len(_edges(colony[i]) & _edges(colony[j])) / 12
        for i in range(5)
        for j in range(5)
        if i != j
    ]
    assert float(edge_diversity(colony)) == pytest.approx(np.mean(pairs), abs=1e-6)
    batched = jax.vmap(edge_diversity)(np.stack([colony, colony[::-1]]))
    np.testing.assert_allclose(batched, [np.mean(pairs)] * 2, atol=1e-6)


def test_edge_counts_match_the_pairwise_table():
    """The O(m n) count formula against the (m, m) table of shared edges, on colonies with
    repeated, reversed and partly shared tours."""
    rng = np.random.default_rng(3)
    for m, n in ((2, 3), (9, 17), (40, 51)):
        base = rng.permutation(n)
        colony = np.stack([rng.permutation(n) if i % 3 else base for i in range(m)])
        colony[-1] = colony[0][::-1]
        shared = shared_edges(colony)
        pairwise = (1 - shared / n)[~np.eye(m, dtype=bool)].mean()
        assert float(edge_diversity(colony)) == pytest.approx(pairwise, abs=1e-6)


def test_bad_shape():
    with pytest.raises(ValueError, match="shape"):
        edge_diversity(np.arange(5))
