"""Don't-look-bit 2-opt / Or-opt (ACOTSP style) against a plain numpy reference.

The reference walks the same city order with the same rules (first improvement over the
radius-pruned candidate list, successor side before predecessor side, the shorter side
reversed, Or-opt's best move over segments of 1-3 cities at c1 among the candidates closer than
the segment's removal gain), one move at a time, so the
JAX search must return the very same tours - both implementations: the vmapped XLA loop
and the numba one the CPU runs (``impl="auto"`` on a CPU, as every other test here uses).
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

from eaco_jax.ops.local_search import best_k, changed_cities, dlb_local_search
from eaco_jax.problems import TSP, load_tsplib


def _reverse(tour, pos, a, length):
    n = len(tour)
    if length > n - length:
        a, length = (a + length) % n, n - length
    idx = [(a + q) % n for q in range(length)]
    cities = [tour[i] for i in idx][::-1]
    for i, c in zip(idx, cities, strict=True):
        tour[i] = c
        pos[c] = i


def _or_move(tour, sa, length, t, rev):
    """Move the segment of ``length`` positions from ``sa`` after relative position ``t``."""
    n = len(tour)
    rel = [tour[(sa + q) % n] for q in range(n)]
    seg, rest = rel[:length], rel[length:]
    seg = seg[::-1] if rev else seg
    cut = t - length + 1
    new_rel = rest[:cut] + seg + rest[cut:]
    for q, c in enumerate(new_rel):
        tour[(sa + q) % n] = c


def reference(tour, order, d, cand, or_opt=False, full_check=False, max_moves=10**9,
              start=None):
    """Plain-Python don't-look-bit local search (the specification of dlb_local_search);
    ``start``: the cities whose bits start clear (None: all)."""
    tour = [int(c) for c in tour]
    n, k = len(tour), cand.shape[1]
    pos = [0] * n
    for i, c in enumerate(tour):
        pos[c] = i
    active = [True] * n if start is None else [bool(a) for a in start]
    rank = {int(c): i for i, c in enumerate(order)}
    ptr, moves, dirty = 0, 0, False
    while any(active) and moves < max_moves:
        c1 = min((c for c in range(n) if active[c]), key=lambda c: (rank[c] - ptr) % n)
        ptr = (rank[c1] + 1) % n
        i1 = pos[c1]
        s1, p1 = tour[(i1 + 1) % n], tour[(i1 - 1) % n]
        move = None
        for h in range(k):  # successor side
            c2 = int(cand[c1, h])
            if not d[c1, c2] < d[c1, s1]:
                break
            s2 = tour[(pos[c2] + 1) % n]
            if c2 != p1 and d[c1, s1] + d[c2, s2] - d[c1, c2] - d[s1, s2] > 0:
                move = (pos[s1], pos[c2], [c1, s1, c2, s2])
                break
        if move is None:
            for h in range(k):  # predecessor side
                c2 = int(cand[c1, h])
                if not d[c1, c2] < d[p1, c1]:
                    break
                p2 = tour[(pos[c2] - 1) % n]
                if c2 != s1 and d[p1, c1] + d[p2, c2] - d[c1, c2] - d[p1, p2] > 0:
                    move = (i1, pos[p2], [c1, p1, c2, p2])
                    break
        if move is not None:
            a, b, ends = move
            _reverse(tour, pos, a, (b - a) % n + 1)
        elif or_opt:
            best, arg = 0.0, None
            segs = [(1, False), (2, False), (3, False), (2, True), (3, True)]
            for length, back in segs:
                sa = (i1 - length + 1) % n if back else i1
                first, last = tour[sa], tour[(sa + length - 1) % n]
                pp, ss = tour[(sa - 1) % n], tour[(sa + length) % n]
                other = first if back else last
                g_rem = d[pp, first] + d[last, ss] - d[pp, ss]
                for h in range(k):
                    c2 = int(cand[c1, h])
                    if not d[c1, c2] < g_rem:  # the gain criterion
                        continue
                    q = (pos[c2] - sa) % n
                    sc, pc = tour[(pos[c2] + 1) % n], tour[(pos[c2] - 1) % n]
                    for side in (0, 1):
                        if q < length or (side == 0 and q == n - 1) or (side == 1 and q == length):
                            continue
                        if side == 0:
                            g = g_rem + d[c2, sc] - d[c1, c2] - d[other, sc]
                        else:
                            g = g_rem + d[pc, c2] - d[c1, c2] - d[pc, other]
                        if g > best:  # strict: the first maximum wins, as argmax
                            rev = (side == 0) if back else (side == 1)
                            nb = sc if side == 0 else pc
                            best, arg = g, (sa, length, q - side, rev,
                                            [pp, ss, first, last, c2, nb])
            if arg is not None:
                sa, length, t, rev, ends = arg
                _or_move(tour, sa, length, t, rev)
                for i, c in enumerate(tour):
                    pos[c] = i
                move = arg
        if move is not None:
            moves += 1
            dirty = True
            for c in ends:
                active[c] = True
        else:
            active[c1] = False
        if full_check and not any(active) and dirty:
            active, dirty = [True] * n, False
    return np.array(tour, np.int32), moves


def _two_opt_moves_left(d, tour, cand):
    """Improving 2-opt moves that the radius-pruned candidate scan can see."""
    n = len(tour)
    pos = np.empty(n, int)
    pos[tour] = np.arange(n)
    left = 0
    for c1 in range(n):
        s1, p1 = tour[(pos[c1] + 1) % n], tour[(pos[c1] - 1) % n]
        for c2 in cand[c1]:
            s2, p2 = tour[(pos[c2] + 1) % n], tour[(pos[c2] - 1) % n]
            if c2 not in (s1, p1):
                left += d[c1, s1] + d[c2, s2] - d[c1, c2] - d[s1, s2] > 0
                left += d[p1, c1] + d[p2, c2] - d[c1, c2] - d[p1, p2] > 0
    return left


def _tours(n, m, seed):
    rng = np.random.default_rng(seed)
    return np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32)


@pytest.fixture(scope="module")
def eil51():
    return load_tsplib("eil51", neighbors=10)


@pytest.mark.parametrize("or_opt", [False, True])
@pytest.mark.parametrize("full_check,block,impl", [
    (False, 8, "xla"), (True, 8, "xla"), (False, 1, "xla"), (True, 3, "xla"),
    (False, 1, "native"), (True, 1, "native")])
def test_matches_numpy_reference_move_for_move(eil51, or_opt, full_check, block, impl):
    d, cand = np.asarray(eil51.dist, np.float64), np.asarray(eil51.neighbors)
    tours, orders = _tours(51, 3, 0), _tours(51, 3, 1)
    out, moves = dlb_local_search(None, tours, eil51.dist, eil51.neighbors, or_opt=or_opt,
                                  full_check=full_check, return_moves=True, order=orders,
                                  block=block, impl=impl)
    for t, o, got, mv in zip(tours, orders, np.asarray(out), np.asarray(moves), strict=True):
        want, want_moves = reference(t, o, d, cand, or_opt, full_check)
        np.testing.assert_array_equal(got, want)
        assert mv == want_moves


@pytest.mark.parametrize("impl,block", [("xla", 1), ("xla", 4), ("native", 1)])
def test_focused_start_matches_reference(eil51, impl, block):
    """Bits clear only at the changed edges' cities (Focused ACO): the same moves as the
    reference started from the same bits, on tours a few edges away from a local optimum."""
    d, cand = np.asarray(eil51.dist, np.float64), np.asarray(eil51.neighbors)
    opt = np.asarray(dlb_local_search(None, _tours(51, 1, 5), eil51.dist, eil51.neighbors,
                                      or_opt=True, full_check=True))[0]
    rng = np.random.default_rng(6)
    tours = []
    for _ in range(4):  # two random segment reversals of the local optimum
        t = opt.copy()
        for _ in range(2):
            a, b = sorted(rng.choice(51, 2, replace=False))
            t[a:b + 1] = t[a:b + 1][::-1]
        tours.append(t)
    tours = np.stack(tours).astype(np.int32)
    orders = _tours(51, 4, 7)
    active = np.asarray(changed_cities(tours, opt))
    assert 0 < active.sum(axis=1).max() <= 8  # two reversals change at most four edges
    out, moves = dlb_local_search(None, tours, eil51.dist, eil51.neighbors, or_opt=True,
                                  return_moves=True, order=orders, block=block, impl=impl,
                                  active=active)
    for t, o, a, got, mv in zip(tours, orders, active, np.asarray(out), np.asarray(moves),
                                strict=True):
        want, want_moves = reference(t, o, d, cand, True, False, start=a)
        np.testing.assert_array_equal(got, want)
        assert mv == want_moves
    # no clear bit: nothing is searched; every bit clear: the unfocused search
    none = dlb_local_search(None, tours, eil51.dist, eil51.neighbors, or_opt=True,
                            order=orders, impl=impl, active=np.zeros_like(active))
    np.testing.assert_array_equal(none, tours)
    full = dlb_local_search(None, tours, eil51.dist, eil51.neighbors, or_opt=True,
                            order=orders, impl=impl, active=np.ones_like(active))
    np.testing.assert_array_equal(full, dlb_local_search(None, tours, eil51.dist,
                                                         eil51.neighbors, or_opt=True,
                                                         order=orders, impl=impl))


def test_changed_cities_by_hand():
    ref = np.arange(8, dtype=np.int32)
    # reversing positions 2..4 replaces edges (1,2), (4,5) by (1,4), (2,5)
    t = np.array([[0, 1, 4, 3, 2, 5, 6, 7], [7, 6, 5, 4, 3, 2, 1, 0], [3, 4, 5, 6, 7, 0, 1, 2]],
                 np.int32)
    got = np.asarray(changed_cities(t, ref))
    assert sorted(np.flatnonzero(got[0])) == [1, 2, 4, 5]
    assert not got[1].any() and not got[2].any()  # the same cycle, reversed or rotated


@pytest.mark.parametrize("or_opt", [False, True])
def test_permutation_never_longer_and_candidate_local_optimum(or_opt):
    p = load_tsplib("kroA100")
    tours = _tours(100, 6, 2)
    out = np.asarray(dlb_local_search(jax.random.key(0), tours, p.dist, p.neighbors,
                                      or_opt=or_opt, full_check=True))
    d, cand = np.asarray(p.dist, np.float64), np.asarray(p.neighbors)
    before, after = np.asarray(p.evaluate(tours)), np.asarray(p.evaluate(out))
    assert np.all(after < before)
    for t in out:
        assert sorted(t) == list(range(100))
        assert _two_opt_moves_left(d, t, cand) == 0
    assert float(after.mean()) < 1.12 * p.optimum


def test_or_opt_reaches_better_tours_than_2opt_alone():
    p = load_tsplib("kroA100")
    tours = _tours(100, 16, 3)
    two = np.asarray(p.evaluate(dlb_local_search(jax.random.key(1), tours, p.dist,
                                                 p.neighbors)))
    both = np.asarray(p.evaluate(dlb_local_search(jax.random.key(1), tours, p.dist,
                                                  p.neighbors, or_opt=True)))
    assert both.mean() < two.mean()


def test_hand_checked_moves():
    # eight points on a 30 x 10 ladder
    sq = TSP.from_coords(np.array([[0, 0], [10, 0], [10, 10], [0, 10], [20, 0], [20, 10],
                                   [30, 0], [30, 10]], float), neighbors=7)
    opt = float(sq.evaluate(np.array([[0, 1, 4, 6, 7, 5, 2, 3]]))[0])
    assert opt == 80.0  # the 30 x 10 rectangle's perimeter
    # city 2 visited between 0 and 1 (length 94): two 2-opt moves (or one Or-opt) fix it
    crossed = np.array([[0, 2, 1, 4, 6, 7, 5, 3]], np.int32)
    out, moves = dlb_local_search(None, crossed, sq.dist, sq.neighbors, full_check=True,
                                  return_moves=True)
    assert float(sq.evaluate(crossed)[0]) > opt
    assert float(sq.evaluate(out)[0]) == opt and int(moves[0]) == 2
    out, moves = dlb_local_search(None, crossed, sq.dist, sq.neighbors, or_opt=True,
                                  full_check=True, return_moves=True)
    assert float(sq.evaluate(out)[0]) == opt
    # a single city out of place on a line of points: Or-opt moves it back in one move
    line = TSP.from_coords(np.c_[np.arange(10) * 10.0, np.zeros(10)], neighbors=4)
    t = np.array([[0, 1, 2, 7, 3, 4, 5, 6, 8, 9]], np.int32)
    out, moves = dlb_local_search(None, t, line.dist, line.neighbors, or_opt=True,
                                  return_moves=True)
    assert float(line.evaluate(out)[0]) == 180.0
    # an optimal tour is left alone
    ident = np.arange(10, dtype=np.int32)[None]
    same, moves = dlb_local_search(None, ident, line.dist, line.neighbors, or_opt=True,
                                   return_moves=True)
    np.testing.assert_array_equal(same, ident)
    assert int(moves[0]) == 0


def test_max_moves_cap_and_best_k(eil51):
    tours = _tours(51, 4, 4)
    capped, moves = dlb_local_search(None, tours, eil51.dist, eil51.neighbors, max_moves=3,
                                     return_moves=True)
    assert np.all(np.asarray(moves) == 3)
    lengths = eil51.evaluate(tours)
    out = best_k(tours, lengths, 2, lambda t: dlb_local_search(None, t, eil51.dist,
                                                                eil51.neighbors))
    out = np.asarray(out)
    best2 = np.argsort(np.asarray(lengths))[:2]
    rest = np.setdiff1d(np.arange(4), best2)
    np.testing.assert_array_equal(out[rest], tours[rest])
    assert np.all(np.asarray(eil51.evaluate(out[best2])) < np.asarray(lengths)[best2])


@pytest.mark.parametrize("ls,best", [("2opt-dlb", None), ("2opt+oropt", 3), ("2opt", 3)])
def test_colony_with_dlb_search_and_best_k(ls, best):
    from eaco_jax import minimize
    from eaco_jax.strategies.graph_eaco import GraphEACO

    p = load_tsplib("eil51")
    res = minimize(p, GraphEACO(num_ants=8, local_search=ls, ls_best_k=best), seed=0,
                   iterations=6)
    tour = np.asarray(res.best_solution)
    assert sorted(tour.tolist()) == list(range(51))
    assert float(res.best_cost) < 1.08 * p.optimum
    with pytest.raises(ValueError, match="ls_best_k"):
        GraphEACO(ls_best_k=0)
