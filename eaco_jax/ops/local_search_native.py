"""The don't-look-bit local search (:func:`eaco_jax.ops.local_search.dlb_local_search`)
compiled to native code with numba, called from inside the jitted colony step on a CPU.

Why: ACOTSP's search is sequential - one city, one candidate scan, one move at a time. As a
``lax.while_loop`` on XLA's CPU backend each of those tiny iterations pays a fixed cost of a
few dozen operations' dispatch, so local search took most of a CPU iteration; compiled to
machine code the same search runs an order of magnitude faster on one core
(``experiments/local_search_native_speed.py`` times both), and the CPU colony keeps up with
ACOTSP at equal time (claims ``tsp-cpu-pcb442-10s``, ``acotsp-cpu-pcb442-10s``). (On a GPU
the XLA loop stays: there thousands of tours run side by side.) The same precedent as the gait
rollouts: native MuJoCo on a CPU, MJX on a GPU.

The search is the very one of :func:`eaco_jax.ops.local_search._dlb_one` - same city order,
same candidate scans, same float32 gains, same moves applied to the same array positions - so
both implementations return identical tours (``tests/test_local_search_native.py`` checks it
on random and TSPLIB tours). Move application is in place, O(segment), as in ACOTSP.
"""

from __future__ import annotations

from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numba
import numpy as np
from jax.experimental.buffer_callback import buffer_callback

Array = jax.Array

#: Or-opt segments (length, starts at the city: False / ends at it: True), in the order of
#: ``local_search._dlb_one`` (its ``lens`` / ``back``), which decides ties between equal gains
_OR_LENS = np.array([1, 2, 3, 2, 3], np.int32)
_OR_BACK = np.array([False, False, False, True, True])


@numba.njit(cache=True, nogil=True)
def _reverse(tour, pos, base, span):  # pragma: no cover - numba
    """Reverse the cyclic positions ``base .. base + span - 1`` in place."""
    n = tour.shape[0]
    i, j = base, (base + span - 1) % n
    for _ in range(span // 2):
        a, b = tour[i], tour[j]
        tour[i], tour[j] = b, a
        pos[b], pos[a] = i, j
        i = i + 1 if i + 1 < n else 0
        j = j - 1 if j > 0 else n - 1


@numba.njit(cache=True, nogil=True)
def _or_move(tour, pos, base, span, t, rev, seg):  # pragma: no cover - numba
    """Move the segment of ``span`` cities at ``base`` to just after relative position ``t``
    (the cities at relative ``span .. t`` move ``span`` places forward), reversed when
    ``rev``: ``local_search._move_positions``' kind 2, in place."""
    n = tour.shape[0]
    for j in range(span):
        seg[j] = tour[(base + j) % n]
    for q in range(t - span + 1):
        c = tour[(base + q + span) % n]
        p = (base + q) % n
        tour[p] = c
        pos[c] = p
    lo = t - span + 1
    for j in range(span):
        c = seg[span - 1 - j] if rev else seg[j]
        p = (base + lo + j) % n
        tour[p] = c
        pos[c] = p


#: how the native search reads a distance (``dist`` is a matrix, or int32 coordinates whose
#: TSPLIB distance it computes exactly: the values of the sparse path's ``CoordDistances``)
MODES = {"matrix": 0, "EUC_2D": 1, "CEIL_2D": 2, "ATT": 3}


@numba.njit(cache=True, nogil=True, inline="always")
def _d(dist, mode, i, j):  # pragma: no cover - numba
    """float32 distance of cities ``i`` and ``j`` (:data:`MODES`)."""
    if mode == 0:
        return np.float32(dist[i, j])
    dx = np.int64(dist[i, 0]) - np.int64(dist[j, 0])
    dy = np.int64(dist[i, 1]) - np.int64(dist[j, 1])
    s = dx * dx + dy * dy
    if mode == 1:  # nint(sqrt(s)) = t  iff  t^2 - t + 1 <= s <= t^2 + t
        t = np.int64(np.floor(np.sqrt(np.float64(s)) + 0.5))
        while t > 0 and s < t * t - t + 1:
            t -= 1
        while s > t * t + t:
            t += 1
        return np.float32(t)
    scale = 1 if mode == 2 else 10  # ceil(sqrt(s / scale)): CEIL_2D, ATT
    t = np.int64(np.ceil(np.sqrt(np.float64(s) / scale)))
    while t > 0 and scale * (t - 1) * (t - 1) >= s:
        t -= 1
    while scale * t * t < s:
        t += 1
    return np.float32(t)


@numba.njit(cache=True, nogil=True)
def _dlb_one(tour, order, dist, cand, cand_d, max_moves, or_opt, full_check, lens, back,
             pos, rank, active, seg, ends, pc2, sc2, pr2, ga, gb, grem,
             mode, active0):  # pragma: no cover
    """One tour, in place: ``local_search._dlb_one`` with ``block=1``. Returns the moves.
    ``active0``: the cities whose bits start clear."""
    n = tour.shape[0]
    k = cand.shape[1]
    n_seg = lens.shape[0]
    neg_inf = np.float32(-np.inf)
    n_active = 0
    for i in range(n):
        pos[tour[i]] = i
        rank[order[i]] = i
        active[i] = active0[i]
        n_active += active[i]
    ptr = 0
    moves = 0
    dirty = False
    while n_active > 0 and moves < max_moves:
        r = ptr  # the first city with a clear bit, in the order from ptr
        while not active[order[r]]:
            r = r + 1 if r + 1 < n else 0
        c1 = order[r]
        i1 = pos[c1]
        a = b = 0
        s1, p1 = tour[(i1 + 1) % n], tour[(i1 - 1) % n]
        kind = 0
        # 2-opt, successor side: reverse s1 .. c2
        rad = _d(dist, mode, c1, s1)
        for h in range(k):
            d12 = cand_d[c1, h]
            if not d12 < rad:
                break
            c2 = cand[c1, h]
            if c2 == p1:
                continue
            s2 = tour[(pos[c2] + 1) % n]
            if rad + _d(dist, mode, c2, s2) - d12 - _d(dist, mode, s1, s2) > 0:
                kind, a, b = 1, pos[s1], pos[c2]
                ends[0], ends[1], ends[2], ends[3] = c1, s1, c2, s2
                break
        if kind == 0:  # predecessor side: reverse c1 .. p2
            rad = _d(dist, mode, p1, c1)
            for h in range(k):
                d12 = cand_d[c1, h]
                if not d12 < rad:
                    break
                c2 = cand[c1, h]
                if c2 == s1:
                    continue
                p2 = tour[(pos[c2] - 1) % n]
                if rad + _d(dist, mode, p2, c2) - d12 - _d(dist, mode, p1, p2) > 0:
                    kind, a, b = 1, i1, pos[p2]
                    ends[0], ends[1], ends[2], ends[3] = c1, p1, c2, p2
                    break
        if kind == 1:
            ends[4], ends[5] = ends[0], ends[1]
            length = (b - a) % n + 1
            if length <= n - length:
                _reverse(tour, pos, a, length)
            else:
                _reverse(tour, pos, (a + length) % n, n - length)
        elif or_opt:  # the Or-opt move of largest gain, first of equals in (segment, c2, side)
            g_max = neg_inf
            for si in range(n_seg):  # each segment's removal gain
                ln = lens[si]
                sa = (i1 - ln + 1) % n if back[si] else i1
                pp, ss = tour[(sa - 1) % n], tour[(sa + ln) % n]
                last = tour[(sa + ln - 1) % n]
                grem[si] = (_d(dist, mode, pp, tour[sa]) + _d(dist, mode, last, ss)
                            - _d(dist, mode, pp, ss))
                g_max = max(g_max, grem[si])
            for h in range(k):  # per candidate, once, where some segment may use it
                if not cand_d[c1, h] < g_max:
                    continue
                c2 = cand[c1, h]
                pc2[h] = pos[c2]
                sc2[h] = tour[(pos[c2] + 1) % n]
                pr2[h] = tour[(pos[c2] - 1) % n]
                ga[h] = _d(dist, mode, c2, sc2[h]) - cand_d[c1, h]
                gb[h] = _d(dist, mode, pr2[h], c2) - cand_d[c1, h]
            best = neg_inf
            b_si, b_h, b_side = 0, 0, 0
            for si in range(n_seg):
                ln = lens[si]
                g_rem = grem[si]
                sa = (i1 - ln + 1) % n if back[si] else i1
                other = tour[sa] if back[si] else tour[(sa + ln - 1) % n]
                for h in range(k):
                    if not cand_d[c1, h] < g_rem:  # the gain criterion (see the docstring)
                        continue
                    q = (pc2[h] - sa) % n
                    if q < ln:
                        continue
                    # g = g_rem + (ga - d(..)) <= g_rem + ga (distances >= 0, rounding is
                    # monotone): a move that cannot beat max(best, 0) is skipped unevaluated,
                    # which changes no result (only a positive best is applied)
                    bar = best if best > 0 else np.float32(0)
                    if q != n - 1 and g_rem + ga[h] > bar:
                        g = g_rem + (ga[h] - _d(dist, mode, other, sc2[h]))
                        if g > best:
                            best, b_si, b_h, b_side = g, si, h, 0
                    bar = best if best > 0 else np.float32(0)
                    if q != ln and g_rem + gb[h] > bar:
                        g = g_rem + (gb[h] - _d(dist, mode, pr2[h], other))
                        if g > best:
                            best, b_si, b_h, b_side = g, si, h, 1
            if best > 0:
                kind = 2
                ln = lens[b_si]
                sa = (i1 - ln + 1) % n if back[b_si] else i1
                c2 = cand[c1, b_h]
                t = (pos[c2] - sa) % n - b_side
                rv = (b_side == 0) if back[b_si] else (b_side == 1)
                ends[0], ends[1] = tour[(sa - 1) % n], tour[(sa + ln) % n]
                ends[2], ends[3] = tour[sa], tour[(sa + ln - 1) % n]
                ends[4] = c2
                ends[5] = tour[(pos[c2] + 1) % n] if b_side == 0 else tour[(pos[c2] - 1) % n]
                _or_move(tour, pos, sa, ln, t, rv, seg)
        if kind == 0:
            active[c1] = False  # searched, nothing found
            n_active -= 1
        else:
            moves += 1
            dirty = True
            for e in range(6):
                if not active[ends[e]]:
                    active[ends[e]] = True
                    n_active += 1
        if full_check and n_active == 0 and dirty:  # one more full pass after moves
            for i in range(n):
                active[i] = True
            n_active = n
            dirty = False
        ptr = rank[c1] + 1 if rank[c1] + 1 < n else 0
    return moves


@numba.njit(cache=True, nogil=True)
def dlb_batch(tours, orders, dist, cand, cand_d, max_moves, or_opt, full_check, mode=0,
              actives=None):
    """Every tour of ``tours`` ``(m, n)`` (copied): (improved tours, moves per tour);
    ``actives`` ``(m, n)``: each tour's cities whose bits start clear (None: all)."""
    m, n = tours.shape
    if actives is None:
        actives = np.ones((m, n), np.bool_)
    out = tours.copy()
    moves = np.zeros(m, np.int32)
    pos = np.empty(n, np.int32)
    rank = np.empty(n, np.int32)
    active = np.empty(n, np.bool_)
    seg = np.empty(8, np.int32)
    ends = np.empty(6, np.int32)
    k = cand.shape[1]
    pc2, sc2, pr2 = np.empty(k, np.int32), np.empty(k, np.int32), np.empty(k, np.int32)
    ga, gb = np.empty(k, np.float32), np.empty(k, np.float32)
    grem = np.empty(_OR_LENS.shape[0], np.float32)
    lens = _OR_LENS
    back = _OR_BACK
    for i in range(m):
        moves[i] = _dlb_one(out[i], orders[i], dist, cand, cand_d, max_moves, or_opt,
                            full_check, lens, back, pos, rank, active, seg, ends, pc2, sc2,
                            pr2, ga, gb, grem, mode, actives[i])
    return out, moves


def _readonly(x) -> np.ndarray:
    """A contiguous read-only view (one numba specialisation, whatever XLA hands over)."""
    x = np.ascontiguousarray(np.asarray(x)).view()
    x.setflags(write=False)
    return x


def _host(ctx, out, tours, orders, dist, cand, cand_d, actives, *, max_moves: int,
          or_opt: bool, full_check: bool, mode: int = 0) -> None:
    """The buffer callback: reads XLA's buffers in place (no device transfer, which on a
    one-thread CPU client would wait for the very computation that waits for this call) and
    writes the results into ``out``. Any leading batch dims (``vmap`` adds them, size 1
    where unbatched) are looped over."""
    del ctx
    args = [_readonly(x) for x in (tours, orders, dist, cand, cand_d, actives)]
    out_tours, out_moves = np.asarray(out[0]), np.asarray(out[1])
    batch = np.broadcast_shapes(*(x.shape[:-2] for x in args))
    for idx in np.ndindex(*batch):
        def at(x, idx=idx):  # this batch element of x (index 0 along its size-1 dims)
            return x[tuple(i if s > 1 else 0 for i, s in zip(idx, x.shape, strict=False))]
        *rest, act = (at(x) for x in args)
        out_tours[idx], out_moves[idx] = dlb_batch(*rest, max_moves, or_opt, full_check, mode,
                                                   act)


@lru_cache(maxsize=2)
def warm_up(coords: bool = False) -> None:
    """Compile (or load from numba's cache) the native search now, while JAX traces the step,
    so that its compile time counts as compile time and not as search time."""
    n = 8
    x = np.arange(n, dtype=np.float32)
    dist = np.abs(x[:, None] - x[None, :])
    cand = np.argsort(dist + np.eye(n, dtype=np.float32) * n, axis=1)[:, :3].astype(np.int32)
    cand_d = np.take_along_axis(dist, cand, axis=1)
    tours = np.array([[0, 4, 1, 5, 2, 6, 3, 7]], np.int32)
    args = [_readonly(x) for x in (tours, np.arange(n, dtype=np.int32)[None], dist, cand, cand_d)]
    if coords:
        args[2] = _readonly(np.stack([np.arange(n), np.zeros(n)], 1).astype(np.int32))
    dlb_batch(*args, 4 * n, True, True, 1 if coords else 0, np.ones((1, n), np.bool_))


@partial(jax.jit, static_argnames=("max_moves", "or_opt", "full_check", "mode"))
def dlb_native(tours: Array, orders: Array, dist: Array, cand: Array, cand_d: Array,
               max_moves: int, or_opt: bool, full_check: bool,
               mode: int = 0, active: Array | None = None) -> tuple[Array, Array]:
    """``local_search._dlb_one`` over tours ``(m, n)`` as one host call: (tours, moves).
    ``dist``: the (n, n) matrix (``mode`` 0), or (n, 2) int32 coordinates (:data:`MODES`);
    ``active``: ``(m, n)`` bool, the cities whose bits start clear (None: all)."""
    warm_up(mode != 0)
    shapes = (jax.ShapeDtypeStruct(tours.shape, jnp.int32),
              jax.ShapeDtypeStruct(tours.shape[:-1], jnp.int32))
    host = partial(_host, max_moves=int(max_moves), or_opt=bool(or_opt),
                   full_check=bool(full_check), mode=int(mode))
    call = buffer_callback(host, shapes, vmap_method="expand_dims")
    if active is None:
        active = jnp.ones(tours.shape, bool)
    return tuple(call(tours, orders, dist, cand, cand_d, jnp.asarray(active, bool)))
