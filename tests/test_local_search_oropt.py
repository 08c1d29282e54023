"""Batched 2-opt + Or-opt (``two_opt(..., or_opt=True)``): several moves applied in one pass
equal the same moves applied one by one; the search ends at a local optimum of both
neighbourhoods over the candidate lists; permutations, never longer; bad input."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from test_local_search_dlb import _or_move, _reverse, _two_opt_moves_left

from eaco_jax.ops.local_search import (
    REVERSE,
    SEGMENT_TO_END,
    SEGMENT_TO_FRONT,
    _apply_disjoint,
    _greedy_disjoint,
    _or_opt_moves,
    two_opt,
)
from eaco_jax.problems import TSP, load_tsplib


def _tours(n, m, seed):
    rng = np.random.default_rng(seed)
    return np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32)


def _apply_one(tour, lo, hi, kind, span, rev):
    """One move of :func:`_apply_disjoint`'s vocabulary, by the test's own list operations."""
    tour = [int(c) for c in tour]
    n = len(tour)
    if kind == REVERSE:
        _reverse(tour, [0] * n, lo, hi - lo + 1)
    elif kind == SEGMENT_TO_END:  # the segment [lo, lo + span) goes after position hi
        _or_move(tour, lo, span, hi - lo, rev)
    else:  # the segment ending at hi goes before lo: the rest of the range goes after it
        seg = tour[hi - span + 1: hi + 1]
        tour[lo: hi + 1] = (seg[::-1] if rev else seg) + tour[lo: hi - span + 1]
    return tour


def _random_disjoint_moves(rng, n, count):
    """Moves on disjoint edge ranges [lo - 1, hi], some starting at 0 or ending at n - 1."""
    cuts = np.sort(rng.choice(np.arange(1, n - 1), size=2 * count, replace=False))
    moves = []
    for lo, hi in cuts.reshape(-1, 2):
        lo, hi = int(lo), int(hi)
        if moves:  # keep one unused edge between ranges
            lo = max(lo, moves[-1][1] + 2)
        if hi - lo < 1:
            continue
        kind = int(rng.integers(1, 4))
        span = int(rng.integers(1, min(3, hi - lo) + 1))
        moves.append((lo, hi, kind, span, bool(rng.integers(2))))
    if moves and moves[0][0] == 1 and rng.integers(2):  # a range from position 0
        moves[0] = (0,) + moves[0][1:]
    return moves


@pytest.mark.parametrize("seed", range(8))
def test_disjoint_moves_at_once_equal_one_by_one(seed):
    rng = np.random.default_rng(seed)
    n = 40
    tour = rng.permutation(n).astype(np.int32)
    moves = _random_disjoint_moves(rng, n, 6)
    if seed % 2:  # and one ending at n - 1 (not with one from 0: they share edge n - 1)
        lo, hi = moves[-1][0], n - 1
        moves[-1] = (lo, hi, moves[-1][2], min(moves[-1][3], hi - lo), moves[-1][4])
        if moves[0][0] == 0:
            moves = moves[1:]
    want = list(tour)
    for mv in moves:
        want = _apply_one(want, *mv)
    lo, hi, kind, span, rev = (jnp.asarray(np.array(c)) for c in zip(*moves, strict=True))
    pos = np.empty(n, np.int32)
    pos[tour] = np.arange(n)
    gain = jnp.arange(len(moves), 0, -1).astype(jnp.float32)  # all accepted
    got, got_pos, applied = _apply_disjoint(
        jnp.asarray(tour), jnp.asarray(pos), gain, lo.astype(jnp.int32), hi.astype(jnp.int32),
        top=len(moves), budget=jnp.int32(99), kind=kind.astype(jnp.int32),
        span=span.astype(jnp.int32), rev=rev.astype(bool))
    assert int(applied) == len(moves)
    np.testing.assert_array_equal(np.asarray(got), want)
    np.testing.assert_array_equal(np.asarray(got_pos)[np.asarray(got)], np.arange(n))


@pytest.mark.parametrize("gains", [(2.0, 1.0), (1.0, 2.0)])
def test_moves_sharing_the_wrap_edge_are_not_both_applied(gains):
    """A range from position 0 and one ending at n - 1 both remove edge n - 1: the better one
    is applied."""
    n = 12
    tour = jnp.arange(n, dtype=jnp.int32)
    moves = [(0, 3, SEGMENT_TO_END, 1, False), (8, n - 1, REVERSE, 0, False)]
    lo, hi, kind, span, rev = (jnp.asarray(np.array(c)) for c in zip(*moves, strict=True))
    got, _, applied = _apply_disjoint(tour, tour, jnp.array(gains), lo, hi, top=2,
                                      budget=jnp.int32(9), kind=kind, span=span, rev=rev)
    assert int(applied) == 1
    best = moves[int(np.argmax(gains))]
    assert list(np.asarray(got)) == _apply_one(list(range(n)), *best)


@pytest.mark.parametrize("seed", range(6))
def test_parallel_acceptance_is_the_sequential_greedy(seed):
    """The rounds of :func:`_greedy_disjoint` accept what the one-by-one greedy accepts (entry
    t taken when valid, clear of every taken s < t, and the budget not yet spent)."""
    rng = np.random.default_rng(seed)
    m = 64
    lo = rng.integers(0, 90, m)
    hi = lo + rng.integers(0, 12 if seed % 2 else 40, m)
    valid = rng.random(m) < 0.8
    overlap = (lo[:, None] - 1 <= hi[None, :]) & (lo[None, :] - 1 <= hi[:, None])
    for budget in (m, 7, 1, 0):
        want, taken = np.zeros(m, bool), 0
        for t in range(m):
            if valid[t] and not np.any(want & overlap[t]) and taken < budget:
                want[t], taken = True, taken + 1
        for unrolled in (0, 1, 4, 80):  # rounds inline before the loop: the same
            got = _greedy_disjoint(jnp.asarray(valid), jnp.asarray(overlap), jnp.int32(budget),
                                   unrolled)
            np.testing.assert_array_equal(np.asarray(got), want)


def _or_moves_left(d, tour, cand):
    """Improving Or-opt moves (segments of 1..3 cities with a city at one end, moved next to one
    of its candidates) whose segment does not straddle the array's end."""
    n = len(tour)
    pos = np.empty(n, int)
    pos[tour] = np.arange(n)
    left = 0
    for c1 in range(n):
        for length, back in [(1, False), (2, False), (3, False), (2, True), (3, True)]:
            sa = pos[c1] - length + 1 if back else pos[c1]
            if sa < 0 or sa + length - 1 > n - 1:
                continue
            first, last = tour[sa], tour[sa + length - 1]
            pp, ss = tour[(sa - 1) % n], tour[(sa + length) % n]
            other = first if back else last
            g_rem = d[pp, first] + d[last, ss] - d[pp, ss]
            for c2 in cand[c1]:
                q = (pos[c2] - sa) % n
                sc, pc = tour[(pos[c2] + 1) % n], tour[(pos[c2] - 1) % n]
                if q < length:
                    continue
                if q != n - 1:
                    left += g_rem + d[c2, sc] - d[c1, c2] - d[other, sc] > 0
                if q != length:
                    left += g_rem + d[pc, c2] - d[c1, c2] - d[pc, other] > 0
    return left


@pytest.mark.parametrize("name,per_step", [("kroA100", 32), ("eil51", 1), ("eil51", 8)])
def test_ends_at_a_two_opt_and_or_opt_local_optimum(name, per_step):
    p = load_tsplib(name, neighbors=10)
    n = p.dist.shape[0]
    tours = _tours(n, 5, 1)
    out, moves = two_opt(tours, p.dist, p.neighbors, or_opt=True, moves_per_step=per_step,
                         max_moves=100 * n, return_moves=True)
    out = np.asarray(out)
    d, cand = np.asarray(p.dist, np.float64), np.asarray(p.neighbors)
    before, after = np.asarray(p.evaluate(tours)), np.asarray(p.evaluate(out))
    assert np.all(after < before) and np.all(np.asarray(moves) > 0)
    for t in out:
        assert sorted(t) == list(range(n))
        assert _two_opt_moves_left(d, t, cand) == 0
        assert _or_moves_left(d, t, cand) == 0


def test_or_opt_improves_two_opt_optima():
    """2-opt local optima still have improving Or-opt moves; the search with or_opt takes them
    (and starting from a 2-opt optimum, it ends shorter)."""
    p = load_tsplib("kroA100", neighbors=10)
    d, cand = np.asarray(p.dist, np.float64), np.asarray(p.neighbors)
    two = np.asarray(two_opt(_tours(100, 6, 5), p.dist, p.neighbors, max_moves=10_000))
    assert all(_or_moves_left(d, t, cand) > 0 for t in two)
    both = np.asarray(two_opt(two, p.dist, p.neighbors, or_opt=True, max_moves=10_000))
    assert np.all(np.asarray(p.evaluate(both)) < np.asarray(p.evaluate(two)))


def test_or_opt_moves_are_one_per_city_with_valid_ranges():
    p = load_tsplib("eil51", neighbors=10)
    tour = jnp.asarray(_tours(51, 1, 3)[0])
    n = 51
    pos = jnp.zeros(n, jnp.int32).at[tour].set(jnp.arange(n, dtype=jnp.int32))
    succ, pred = tour[(pos + 1) % n], tour[(pos - 1) % n]
    cand = jnp.asarray(p.neighbors)
    cand_d = p.dist[jnp.arange(n)[:, None], cand]
    gain, lo, hi, kind, span, rev = (np.asarray(x) for x in _or_opt_moves(
        tour, pos, succ, pred, p.dist, cand, cand_d))
    ok = np.isfinite(gain)
    assert gain.shape == (n,) and ok.sum() > 40
    assert np.all((0 <= lo[ok]) & (lo[ok] < hi[ok]) & (hi[ok] <= n - 1))
    assert np.all(np.isin(kind[ok], [SEGMENT_TO_END, SEGMENT_TO_FRONT]))
    assert np.all((1 <= span[ok]) & (span[ok] <= 3) & (span[ok] < hi[ok] - lo[ok] + 1))
    assert {SEGMENT_TO_END, SEGMENT_TO_FRONT} <= set(kind[ok])
    # each move, applied alone by the test's list operations, shortens the tour by its gain
    before = float(p.evaluate(tour[None])[0])
    for c in np.flatnonzero(ok):
        after = _apply_one(np.asarray(tour), lo[c], hi[c], kind[c], span[c], rev[c])
        assert sorted(after) == list(range(n))
        assert float(p.evaluate(np.array([after]))[0]) == pytest.approx(before - gain[c])


def test_or_opt_needs_eight_cities():
    sq = TSP.from_coords(np.random.default_rng(0).random((7, 2)).astype(np.float32))
    with pytest.raises(ValueError, match="Or-opt needs at least 8 cities"):
        two_opt(_tours(7, 1, 0), sq.dist, or_opt=True)


@pytest.mark.parametrize("best", [None, 3])
def test_colony_with_or_2opt(best):
    """GraphEACO(local_search="or-2opt") runs the batched 2-opt + Or-opt; on eil51 it ends
    shorter than 2-opt from the same seed (the tours built in the first iteration are the same:
    the ant keys do not depend on the local search)."""
    from eaco_jax import minimize
    from eaco_jax.strategies.graph_eaco import GraphEACO

    p = load_tsplib("eil51")
    res = {ls: minimize(p, GraphEACO(num_ants=8, local_search=ls, ls_best_k=best), seed=0,
                        iterations=1) for ls in ("2opt", "or-2opt")}
    tour = np.asarray(res["or-2opt"].best_solution)
    assert sorted(tour.tolist()) == list(range(51))
    assert float(res["or-2opt"].best_cost) < float(res["2opt"].best_cost)


def test_colony_passes_moves_per_step_to_the_search():
    """GraphEACO.ls_moves_per_step is the batched search's moves_per_step: its local search
    gives two_opt's tours for that value, which differ between 1 and the default."""
    from eaco_jax.strategies.graph_eaco import GraphEACO

    p = load_tsplib("eil51")
    tours = jnp.asarray(_tours(51, 6, 11))
    got = {}
    for per_step in (1, GraphEACO().ls_moves_per_step):
        st = GraphEACO(num_ants=6, local_search="or-2opt", ls_moves_per_step=per_step)
        got[per_step] = np.asarray(st._local_search(tours, p))
        want = two_opt(tours, p.dist, p.neighbors, or_opt=True, moves_per_step=per_step)
        np.testing.assert_array_equal(got[per_step], np.asarray(want))
    assert not np.array_equal(*got.values())
    with pytest.raises(ValueError, match="ls_moves_per_step must be >= 1"):
        GraphEACO(ls_moves_per_step=0)


def test_colony_scans_the_first_ls_neighbors_candidates():
    """GraphEACO.ls_neighbors=K searches on the first K candidates of each list: the tours of
    two_opt with those lists, not those of the whole lists."""
    from eaco_jax.strategies.graph_eaco import GraphEACO

    p = load_tsplib("kroA100")
    tours = jnp.asarray(_tours(100, 6, 12))
    got = np.asarray(GraphEACO(num_ants=6, local_search="or-2opt", ls_neighbors=4)
                     ._local_search(tours, p))
    want = two_opt(tours, p.dist, p.neighbors[:, :4], or_opt=True,
                   moves_per_step=GraphEACO().ls_moves_per_step)
    np.testing.assert_array_equal(got, np.asarray(want))
    full = np.asarray(GraphEACO(num_ants=6, local_search="or-2opt")._local_search(tours, p))
    assert not np.array_equal(got, full)
    with pytest.raises(ValueError, match="ls_neighbors must be >= 1"):
        GraphEACO(ls_neighbors=0)
