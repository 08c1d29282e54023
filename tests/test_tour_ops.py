"""Crossover and mutation operators on tours."""

from __future__ import annotations

import jax
import numpy as np

from eaco_jax.ops.tour_ops import erx, inversion_mutation, pmx, pmx_at, swap_mutation

N = 40


def _edges(t) -> set:
    t = np.asarray(t)
    return {frozenset((int(t[i]), int(t[(i + 1) % len(t)]))) for i in range(len(t))}


def _parents(m: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    a = np.stack([rng.permutation(N) for _ in range(m)]).astype(np.int32)
    b = np.stack([rng.permutation(N) for _ in range(m)]).astype(np.int32)
    return a, b


def _is_perm(t) -> bool:
    return sorted(np.asarray(t).tolist()) == list(range(len(t)))


def test_erx_children_are_permutations_with_parent_edges():
    a, b = _parents(16)
    keys = jax.random.split(jax.random.key(0), 16)
    kids = np.asarray(jax.jit(jax.vmap(erx))(keys, a, b))
    inherited = []
    for ka, kb, kid in zip(a, b, kids, strict=True):
        assert _is_perm(kid) and kid[0] == ka[0]
        inherited.append(len(_edges(kid) & (_edges(ka) | _edges(kb))) / N)
    # ERX keeps most parental edges even for unrelated random parents (dead ends add a few)
    assert np.mean(inherited) > 0.85, np.mean(inherited)


def test_erx_of_identical_parents_is_the_parent_cycle():
    a, _ = _parents(8, seed=1)
    keys = jax.random.split(jax.random.key(1), 8)
    kids = np.asarray(jax.jit(jax.vmap(erx))(keys, a, a))
    for ka, kid in zip(a, kids, strict=True):
        assert _edges(kid) == _edges(ka)


def test_erx_related_parents_keep_shared_edges():
    a, _ = _parents(1, seed=2)
    b = a.copy()
    b[0, 10:20] = b[0, 10:20][::-1]  # one 2-opt move apart: shares all but two edges
    kid = np.asarray(erx(jax.random.key(2), a[0], b[0]))
    shared = _edges(a[0]) & _edges(b[0])
    assert len(shared & _edges(kid)) >= len(shared) - 2


def test_pmx_keeps_segment_and_positions():
    a, b = _parents(8, seed=3)
    for lo, hi in [(5, 20), (0, 0), (0, N - 1), (30, 39)]:
        kids = np.asarray(jax.vmap(lambda x, y, lo=lo, hi=hi: pmx_at(x, y, lo, hi))(a, b))
        for ka, kb, kid in zip(a, b, kids, strict=True):
            assert _is_perm(kid)
            np.testing.assert_array_equal(kid[lo : hi + 1], ka[lo : hi + 1])
            seg = set(ka[lo : hi + 1].tolist())
            for p in range(N):
                if not lo <= p <= hi and kb[p] not in seg:
                    assert kid[p] == kb[p]  # no conflict -> parent_b's city stays
    keys = jax.random.split(jax.random.key(3), 8)
    kids = np.asarray(jax.jit(jax.vmap(pmx))(keys, a, b))
    assert all(_is_perm(k) for k in kids)


def test_mutations_are_permutations_that_change_the_tour():
    a, _ = _parents(32, seed=4)
    keys = jax.random.split(jax.random.key(4), 32)
    inv = np.asarray(jax.jit(jax.vmap(inversion_mutation))(keys, a))
    swp = np.asarray(jax.jit(jax.vmap(swap_mutation))(keys, a))
    for t, ti, ts in zip(a, inv, swp, strict=True):
        assert _is_perm(ti) and _is_perm(ts)
        assert _edges(ti) != _edges(t)  # the cycle itself changes, not just its orientation
        assert _edges(ts) != _edges(t)
        assert np.sum(ts != t) == 2
    small = np.arange(4, dtype=np.int32)
    keys = jax.random.split(jax.random.key(5), 10)
    for t in np.asarray(jax.vmap(inversion_mutation, (0, None))(keys, small)):
        assert _edges(t) != _edges(small)
