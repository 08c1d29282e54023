"""Merging the improvements of several ants (``ops/tour_merge.py``): the merged tour is one
cycle, takes every disjoint improvement that keeps it one, and its gain is exact."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.errors import ConfigError
from eaco_jax.ops.tour_merge import (
    is_single_cycle,
    merge_improvements,
    neighbour_pairs,
    tour_from_pairs,
)
from eaco_jax.problems.tsp_sparse import SparseTSP
from eaco_jax.strategies.graph_eaco import GraphEACO


def _edges(t) -> set[frozenset]:
    t = np.asarray(t)
    return set(map(frozenset, zip(t.tolist(), np.roll(t, -1).tolist(), strict=True)))


def _instance(n: int, seed: int = 0) -> np.ndarray:
    xy = np.random.default_rng(seed).uniform(0, 1000, (n, 2))
    return np.rint(np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))).astype(np.float32)


def _length(d: np.ndarray, t) -> float:
    t = np.asarray(t)
    return float(d[t, np.roll(t, -1)].sum())


def _reverse(t: np.ndarray, i: int, j: int) -> np.ndarray:
    t = t.copy()
    t[i:j + 1] = t[i:j + 1][::-1]
    return t


def _cycles(pairs: np.ndarray) -> int:
    """Connected components of a 2-regular neighbour table, by walking it."""
    seen, count = np.zeros(len(pairs), bool), 0
    for start in range(len(pairs)):
        if seen[start]:
            continue
        count += 1
        prev, cur = -1, start
        while not seen[cur]:
            seen[cur] = True
            a, b = pairs[cur]
            prev, cur = cur, (b if a == prev else a)
    return count


def _reference_merge(ref: np.ndarray, ants: np.ndarray, d: np.ndarray, top: int):
    """The rule of the module docstring, one city and one walk at a time."""
    rp = np.asarray(neighbour_pairs(jnp.asarray(ref)))
    gains, touched, pairs = [], [], []
    for a in ants:
        ap = np.asarray(neighbour_pairs(jnp.asarray(a)))
        touched.append(np.array([set(ap[c]) != set(rp[c]) for c in range(len(ref))]))
        pairs.append(ap)
        gains.append(_length(d, ref) - _length(d, a))
    table, used, total, count = rp.copy(), np.zeros(len(ref), bool), 0.0, 0
    for a in np.argsort(-np.asarray(gains), kind="stable")[:top]:
        if gains[a] <= 0 or np.any(touched[a] & used):
            continue
        trial = np.where(touched[a][:, None], pairs[a], table)
        if _cycles(trial) == 1:
            table, used, total, count = trial, used | touched[a], total + gains[a], count + 1
    return table, total, count


def test_a_tour_round_trips_through_its_neighbour_pairs():
    rng = np.random.default_rng(0)
    for n in (3, 4, 17, 200):
        t = rng.permutation(n)
        pairs = neighbour_pairs(jnp.asarray(t))
        assert bool(is_single_cycle(pairs))
        back = np.asarray(tour_from_pairs(pairs))
        assert back[0] == 0 and sorted(back) == list(range(n))
        assert _edges(back) == _edges(t)


def test_subtours_are_not_one_cycle():
    pairs = np.zeros((21, 2), np.int32)
    for cycle in (list(range(0, 10)), list(range(10, 17)), list(range(17, 21))):
        for i, c in enumerate(cycle):
            pairs[c] = [cycle[i - 1], cycle[(i + 1) % len(cycle)]]
    assert not bool(is_single_cycle(jnp.asarray(pairs)))
    assert bool(is_single_cycle(jnp.asarray(pairs[:10])))  # the first cycle alone is one


def test_disjoint_improvements_all_merge_with_the_exact_gain():
    d = _instance(200, 1)
    xy_order = np.argsort(np.arange(200))  # any tour; the "good" one is a local optimum
    from eaco_jax.ops.local_search import two_opt

    good = np.asarray(two_opt(xy_order[None].astype(np.int32), d, None))[0]
    segments = [(5, 20), (40, 60), (100, 130), (150, 190)]
    ref = good.copy()
    for i, j in segments:
        ref = _reverse(ref, i, j)
    ants = np.stack([_reverse(ref, i, j) for i, j in segments] + [_reverse(ref, 25, 35)])
    assert all(_length(d, a) < _length(d, ref) for a in ants[:4])
    assert _length(d, ants[4]) > _length(d, ref)  # undoes nothing: worse
    tour, gain, count, worst = merge_improvements(jnp.asarray(ref), jnp.asarray(ants),
                                                  jnp.asarray(d), top=5)
    tour = np.asarray(tour)
    assert int(count) == 4 and int(worst) == 4
    assert _edges(tour) == _edges(good)
    assert float(gain) == _length(d, ref) - _length(d, tour)


def test_crossing_moves_that_would_cut_the_tour_keep_only_the_better():
    """Reversals [i, j] and [k, l] with i < k <= j < l: each is a tour, both together are
    two cycles, though they touch disjoint cities."""
    d = _instance(120, 2)
    rng = np.random.default_rng(3)
    ref = rng.permutation(120)
    for _ in range(1000):
        i, k, j, ll = sorted(rng.choice(np.arange(2, 118), 4, replace=False))
        if k - i < 3 or j - k < 3 or ll - j < 3:
            continue
        a, b = _reverse(ref, i, j), _reverse(ref, k, ll)
        ga, gb = _length(d, ref) - _length(d, a), _length(d, ref) - _length(d, b)
        if ga > 0 and gb > 0 and ga != gb:
            break
    else:
        pytest.fail("no pair of improving crossing reversals found")
    tour, gain, count, _ = merge_improvements(jnp.asarray(ref), jnp.asarray(np.stack([a, b])),
                                              jnp.asarray(d), top=2)
    assert int(count) == 1
    assert float(gain) == max(ga, gb)
    assert _edges(np.asarray(tour)) == _edges(a if ga > gb else b)


@pytest.mark.parametrize("seed", range(6))
def test_merge_equals_the_one_at_a_time_rule(seed):
    """Random reference, ants = it after a few random 2-opt moves each: the merged tour,
    gain and count equal those of a plain-Python greedy with a walk per check."""
    rng = np.random.default_rng(seed)
    n, m = 150, 12
    d = _instance(n, seed)
    ref = rng.permutation(n)
    ants = []
    for _ in range(m):
        t = ref.copy()
        for _ in range(rng.integers(1, 3)):
            i = rng.integers(0, n - 10)
            t = _reverse(t, i, i + rng.integers(2, 9))
        ants.append(t)
    ants = np.stack(ants)
    table, total, count = _reference_merge(ref, ants, d, top=8)
    tour, gain, got, worst = merge_improvements(jnp.asarray(ref), jnp.asarray(ants),
                                                jnp.asarray(d), top=8)
    assert int(got) == count and count >= 2  # the case exercises a real merge
    assert float(gain) == total
    tour = np.asarray(tour)
    assert sorted(tour) == list(range(n))
    assert _edges(tour) == _edges(np.asarray(tour_from_pairs(jnp.asarray(table))))
    assert _length(d, tour) == _length(d, ref) - total
    assert int(worst) == int(np.argmin([_length(d, ref) - _length(d, a) for a in ants]))


def test_no_improving_ant_leaves_the_reference():
    d = _instance(60, 4)
    from eaco_jax.ops.local_search import two_opt

    ref = np.asarray(two_opt(np.arange(60, dtype=np.int32)[None], d, None))[0]
    ants = np.stack([_reverse(ref, 3, 20), _reverse(ref, 30, 50)])  # both worse
    tour, gain, count, _ = merge_improvements(jnp.asarray(ref), jnp.asarray(ants),
                                              jnp.asarray(d), top=2)
    assert int(count) == 0 and float(gain) == 0.0
    assert _edges(np.asarray(tour)) == _edges(ref)


def test_a_merging_colony_puts_the_merge_in_its_worst_ants_place():
    """Same state and key: the colony's ants equal the unmerged ones except the worst
    one's slot, which holds a tour shorter than every ant."""
    rng = np.random.default_rng(5)
    p = SparseTSP.from_coords(rng.integers(0, 100_000, (400, 2)), neighbors=8)
    kw = dict(num_ants=16, local_search="or-2opt", max_new_edges=4, construction="moves",
              ls_focus_width=16, seed_tour=True)
    off, on = GraphEACO(**kw), GraphEACO(**kw, merge_ants=16)
    state = ea.minimize(p, off, seed=0, iterations=1).state
    # a worse best tour than the search's: a few segments reversed, each an ant can repair
    best = np.asarray(state.best_solution).copy()
    for i in (20, 120, 220, 320):
        best = _reverse(best, i, i + 30)
    state = state.replace(best_solution=jnp.asarray(best, jnp.int32),
                          best_cost=jnp.float32(p.exact_length(best)))
    key = jax.random.PRNGKey(7)
    plain, _ = jax.jit(off.ask)(key, state, p)
    merged, _ = jax.jit(on.ask)(key, state, p)
    plain, merged = np.asarray(plain), np.asarray(merged)
    lengths = np.array([p.exact_length(t) for t in plain])
    differ = np.flatnonzero(np.any(plain != merged, axis=1))
    assert differ.tolist() == [int(np.argmax(lengths))]
    new = merged[differ[0]]
    assert sorted(new) == list(range(400))
    assert p.exact_length(new) < lengths.min()


@pytest.mark.parametrize("bad", [1, 0, -3, True, 2.5])
def test_merge_ants_must_be_an_integer_of_at_least_two(bad):
    with pytest.raises(ConfigError, match="merge_ants must be an integer >= 2"):
        GraphEACO(num_ants=4, max_new_edges=4, construction="moves", merge_ants=bad)


def test_merge_ants_needs_focused_construction():
    with pytest.raises(ConfigError, match="max-new-edges"):
        GraphEACO(num_ants=4, merge_ants=4)


def test_a_merging_colony_runs_seeds_vmapped():
    """Under vmap over seeds the one-cycle check's ``lax.cond`` becomes a select: both seeds
    still return tours, each the exact length the colony reports."""
    rng = np.random.default_rng(0)
    p = SparseTSP.from_coords(rng.integers(0, 100_000, (300, 2)), neighbors=8)
    st = GraphEACO(num_ants=8, local_search="or-2opt", max_new_edges=4, construction="moves",
                   ls_focus_width=16, merge_ants=8, seed_tour=True)
    res = ea.minimize(p, st, seed=[0, 1], iterations=3)
    for tour, cost in zip(np.asarray(res.best_solution), np.asarray(res.best_cost), strict=True):
        assert sorted(tour) == list(range(300))
        assert p.exact_length(tour) == cost
