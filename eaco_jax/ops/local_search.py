"""Tour improvement by 2-opt (and Or-opt), batched over the colony.

Each tour is improved by a ``lax.while_loop`` of improvement steps, ``vmap``-ed over the ants,
so one call polishes the whole colony without Python loops.

One step on one tour:

1. keep ``pos[c]`` (position of city ``c``) next to the tour, so successor / predecessor of
   every city is a gather;
2. with candidate lists ``neighbors`` ``(n, k)``, evaluate for every city ``a`` and every
   candidate ``c`` in ``a``'s list the two 2-opt moves that create the edge ``(a, c)``:
   "successor" (remove ``(a, succ a)``, ``(c, succ c)``; add ``(a, c)``, ``(succ a, succ c)``)
   and "predecessor" (the mirror image) - ``2 n k`` gains, O(n k), and keep each city's best;
3. of the ``moves_per_step`` best improving moves, accept greedily (by gain) those whose removed
   edges and reversed segments are disjoint from the already accepted ones; disjoint reversals
   commute and their gains add, so all are applied in ONE O(n) pass of index arithmetic
   (``tour[p] <- tour[lo + hi - p]`` inside each accepted ``[lo, hi]``, found by prefix sums).
   ``moves_per_step=1`` is classic best-improvement 2-opt; the batch cuts the number of
   steps (the vmapped loop runs as long as its slowest ant).

With ``or_opt=True`` ("Or-2opt") each city also proposes its best Or-opt move (a segment of
1-3 cities with the city at one end, moved next to one of its candidates, either
orientation); such a move is a rotation of a position range, so it joins the same greedy
disjoint batch as the reversals (:func:`_apply_disjoint`, :func:`_or_opt_moves`).

Only strictly positive gains are applied; with integer distances held exactly in float32 the
loop ends at a 2-opt local optimum (w.r.t. the candidate lists), or after ``max_moves`` moves.
Without ``neighbors`` every city is a candidate of every other (``k = n - 1``), the full
O(n^2) neighbourhood. A move that shortens the tour always creates an edge ``(a, c)`` shorter
than one of the removed edges at ``a`` (Bentley 1992), so lists of the nearest cities lose
little.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import jax
import jax.numpy as jnp

from eaco_jax.errors import ConfigError
from eaco_jax.ops.compaction import blocks_of, first_true, prefix_sum

Array = jax.Array

#: Or-opt moves segments of 1..OR_OPT_MAX cities
OR_OPT_MAX = 3


def as_distances(dist: Any) -> Any:
    """``dist`` as the searches read it: a float32 (n, n) array, or unchanged when it computes
    its entries when indexed (``on_the_fly``: the sparse TSP's coordinate distances, indexed
    ``dist[a, b]`` like a matrix, so every search runs on it unchanged)."""
    if getattr(dist, "on_the_fly", False):
        return dist
    return jnp.asarray(dist, jnp.float32)


def _check(tours: Array, dist: Array, neighbors: Array | None, or_opt: bool = False) -> None:
    if tours.ndim != 2:
        raise ValueError(f"tours must have shape (m, n), got {tours.shape}")
    n = tours.shape[1]
    if dist.shape != (n, n):
        raise ValueError(
            f"dist must have shape ({n}, {n}) for tours of {n} cities, got {dist.shape}"
        )
    if n < 4:
        raise ConfigError(f"local search needs at least 4 cities, got {n}; use "
                          "local_search='none' (eaco tsp --local-search none)")
    if or_opt and n < 2 * OR_OPT_MAX + 2:
        raise ConfigError(f"Or-opt needs at least {2 * OR_OPT_MAX + 2} cities, got {n}; use "
                          "local_search='2opt' or 'none' (eaco tsp --local-search 2opt)")
    if neighbors is not None and (neighbors.ndim != 2 or neighbors.shape[0] != n):
        raise ValueError(f"neighbors must have shape ({n}, k), got {neighbors.shape}")


def _candidates(dist: Array, neighbors: Array | None) -> Array:
    """The candidate lists, or every other city (sorted by distance) when None."""
    if neighbors is not None:
        return jnp.asarray(neighbors, jnp.int32)
    if getattr(dist, "on_the_fly", False):
        raise ConfigError("a search on distances computed from coordinates needs candidate "
                          "lists (neighbors)")
    n = dist.shape[0]
    d = jnp.where(jnp.eye(n, dtype=bool), jnp.inf, dist)
    return jnp.argsort(d, axis=1)[:, : n - 1].astype(jnp.int32)


def _default_max_moves(n: int, max_moves: int | None) -> int:
    return 4 * n if max_moves is None else int(max_moves)


#: move kinds of the batched search: reverse [lo, hi]; rotate [lo, hi] so that its first
#: ``span`` positions go to its end; ... so that its last ``span`` positions go to its front
REVERSE, SEGMENT_TO_END, SEGMENT_TO_FRONT = 1, 2, 3


def _greedy_disjoint(valid: Array, overlap: Array, budget: Array, unrolled: int = 0) -> Array:
    """Greedy acceptance in index order, in parallel rounds: entry ``t`` is accepted when it is
    ``valid`` and overlaps no accepted ``s < t``, and only the first ``budget`` are kept.

    The sequential greedy (one decision per entry) costs ``len(valid)`` dependent steps, each a
    few kernels on a GPU; here every round accepts all undecided entries that no undecided
    better one overlaps, and drops those that overlap what was accepted. Entries decided in
    a round are decided as the greedy decides them (their better overlapping entries are all
    rejected), so the result is the greedy's, in as many rounds as the longest chain of
    overlaps (a few), not ``len(valid)`` steps. Truncating to the first ``budget`` accepted
    is the greedy with a budget: its decisions before the budget runs out are the same.

    ``unrolled``: rounds run inline before the loop (a round with nothing undecided changes
    nothing, so the result is the same). On a GPU each turn of a loop whose end depends on
    the data waits for the host to read its test; a vmapped colony's loop runs as many rounds
    as its longest chain, usually 3 or 4, and the unrolled ones skip those waits.
    """
    before = jnp.tril(overlap, -1)  # before[t, s]: s < t and they overlap

    def round_(carry):
        undecided, acc = carry
        take = undecided & ~jnp.any(before & undecided[None, :], axis=1)
        acc = acc | take
        clash = jnp.any(overlap & take[None, :], axis=1)
        return undecided & ~take & ~clash, acc

    carry = (valid, jnp.zeros_like(valid))
    for _ in range(unrolled):
        carry = round_(carry)
    _, acc = jax.lax.while_loop(lambda c: jnp.any(c[0]), round_, carry)
    return acc & (jnp.cumsum(acc) <= budget)


def _greedy_sequential(valid: Array, overlap: Array, budget: Array) -> Array:
    """The same greedy acceptance as :func:`_greedy_disjoint`, one decision per entry in index
    order (``len(valid)`` dependent steps): the reference that the rounds reproduce."""

    def accept(t, acc):
        ok = valid[t] & ~jnp.any(acc & overlap[t]) & (acc.sum() < budget)
        return acc.at[t].set(ok)

    return jax.lax.fori_loop(0, valid.shape[0], accept, jnp.zeros_like(valid))


#: how a step of :func:`two_opt` accepts its disjoint moves (the same moves either way):
#: "rounds" in parallel rounds (:func:`_greedy_disjoint`), "unrolled" the same with its first
#: :data:`UNROLLED_ROUNDS` rounds inline, "sequential" one by one
ACCEPTANCES = ("rounds", "unrolled", "sequential")
#: the rounds "unrolled" runs before its loop (the same moves whatever its value; a cost choice)
UNROLLED_ROUNDS = 4

#: how :func:`two_opt` loops over the steps of a focused search (the same tours either way):
#: "ants", a vmapped loop per tour; "colony", one loop over the colony (:func:`_colony_steps`)
LOOPS = ("ants", "colony")


def _apply_disjoint(
    tour: Array,
    pos: Array,
    gain: Array,
    lo: Array,
    hi: Array,
    top: int,
    budget: Array,
    kind: Array | None = None,
    span: Array | None = None,
    rev: Array | None = None,
    acceptance: str = "rounds",
    ends: bool = False,
) -> tuple[Array, ...]:
    """Apply several improving moves at once, greedily by gain, if they touch disjoint edges.

    ``gain``/``lo``/``hi`` describe one candidate move per entry on the positions
    ``[lo, hi]`` (``0 <= lo < hi <= n - 1``), removing edges in ``[lo - 1, hi]`` only (edge
    ``e`` joins positions ``e`` and ``e + 1``; edge ``-1`` is edge ``n - 1``). ``kind`` (default
    all :data:`REVERSE`): reverse ``[lo, hi]`` (2-opt), or move the segment of ``span``
    positions at its front to its end / at its end to its front, reversed where ``rev``
    (Or-opt). Of the ``top`` best, a move is accepted when its edge range is disjoint from
    every better accepted one; such moves commute and their gains add up, so all of them are
    applied in one O(n) pass (``acceptance``: see :data:`ACCEPTANCES`). Returns (tour, pos,
    applied), and with ``ends`` (the focused search) also the cities at the ends of the edges
    the accepted moves removed ``(6 top,)`` (the only cities whose tour neighbours can change;
    ``n`` for none), the positions rewritten by :func:`_moved_positions`.
    """
    n = tour.shape[0]
    top = min(top, gain.shape[0])
    top_g, top_i = jax.lax.top_k(gain, top)
    tl, th = lo[top_i], hi[top_i]
    overlap = (tl[:, None] - 1 <= th[None, :]) & (tl[None, :] - 1 <= th[:, None])
    # a range starting at 0 removes edge n - 1, which a range ending at n - 1 also removes
    overlap = overlap | ((tl[:, None] == 0) & (th[None, :] == n - 1))
    overlap = overlap | ((tl[None, :] == 0) & (th[:, None] == n - 1))

    if acceptance == "sequential":
        acc = _greedy_sequential(top_g > 0, overlap, budget)
    else:
        acc = _greedy_disjoint(top_g > 0, overlap, budget,
                               UNROLLED_ROUNDS if acceptance == "unrolled" else 0)
    one = acc.astype(jnp.int32)
    idx = jnp.arange(n, dtype=jnp.int32)
    if ends:  # old positions at the ends of every removed edge (edge e: e and e + 1)
        if kind is None:
            cut = jnp.stack([tl - 1, tl, tl - 1, tl, th, th + 1], axis=1)
        else:
            ln_t = span[top_i]
            mid = jnp.where(kind[top_i] == SEGMENT_TO_END, tl + ln_t - 1, th - ln_t)
            cut = jnp.stack([tl - 1, tl, mid, mid + 1, th, th + 1], axis=1)
        cut_cities = jnp.where(acc[:, None], tour[cut % n], n).reshape(-1)
    if kind is None:  # reversals only: the piecewise reflection p -> lo + hi - p
        w = jnp.where(acc, tl + th, 0)
        mirror = jnp.zeros(n + 1, jnp.int32).at[tl].add(w).at[th + 1].add(-w).cumsum()[:n]
        inside = jnp.zeros(n + 1, jnp.int32).at[tl].add(one).at[th + 1].add(-one).cumsum()[:n]
        inside = inside > 0
        tour = tour[jnp.where(inside, mirror - idx, idx)]
        if ends:  # the focused search: the moved positions only
            return tour, _moved_positions(pos, tour, inside, idx), one.sum(), cut_cities
        return tour, jnp.where(inside[pos], mirror[pos] - pos, pos), one.sum()
    # the accepted move (if any) that owns each position, by a prefix sum over the ranges
    # (each entry one label, or two of adjacent ranges apart: at most top in size)
    label = jnp.where(acc, jnp.arange(1, top + 1, dtype=jnp.int32), 0)
    owner = jnp.zeros(blocks_of(n + 1), jnp.int32).at[tl].add(label).at[th + 1].add(-label)
    owner = prefix_sum(owner, top)[:n]  # (made at the padded length: no padded copy)
    inside = owner > 0
    o = jnp.maximum(owner - 1, 0)
    a, b = tl[o], th[o]
    kd = jnp.where(inside, kind[top_i][o], 0)
    ln, rv = span[top_i][o], rev[top_i][o]

    def seg(j):  # offset inside a moved segment, reversed where rev
        return jnp.where(rv, ln - 1 - j, j)

    # new position p takes the city of old position src[p]
    src = jnp.where(kd == REVERSE, a + b - idx, idx)
    src = jnp.where((kd == SEGMENT_TO_END) & (idx <= b - ln), idx + ln, src)
    src = jnp.where((kd == SEGMENT_TO_END) & (idx > b - ln), a + seg(idx - (b - ln + 1)), src)
    src = jnp.where((kd == SEGMENT_TO_FRONT) & (idx >= a + ln), idx - ln, src)
    src = jnp.where((kd == SEGMENT_TO_FRONT) & (idx < a + ln), b - ln + 1 + seg(idx - a), src)
    if ends:  # the focused search: the moved positions only
        tour = tour[src]
        return tour, _moved_positions(pos, tour, inside, idx), one.sum(), cut_cities
    # old position q goes to dst[q]
    dst = jnp.where(kd == REVERSE, a + b - idx, idx)
    dst = jnp.where((kd == SEGMENT_TO_END) & (idx < a + ln), b - ln + 1 + seg(idx - a), dst)
    dst = jnp.where((kd == SEGMENT_TO_END) & (idx >= a + ln), idx - ln, dst)
    dst = jnp.where((kd == SEGMENT_TO_FRONT) & (idx > b - ln), a + seg(idx - (b - ln + 1)), dst)
    dst = jnp.where((kd == SEGMENT_TO_FRONT) & (idx <= b - ln), idx + ln, dst)
    return tour[src], dst[pos], one.sum()


def _moved_positions(pos: Array, tour: Array, inside: Array, idx: Array) -> Array:
    """``pos`` of the new ``tour`` rewritten at the positions ``inside`` the accepted moves'
    ranges only (a scatter of those; the rest keep theirs) instead of a gather of all ``n``
    cities' positions through the moves' map: the focused search's few short moves touch
    few positions (the full search keeps the gather; on a CPU the scatter was no faster
    there)."""
    n = tour.shape[0]
    return pos.at[jnp.where(inside, tour, n)].set(idx, mode="drop")


def _or_opt_moves(
    tour: Array, pos: Array, succ: Array, pred: Array, dist: Array, cand: Array, cand_d: Array,
    at: Array | None = None,
) -> tuple[Array, ...]:
    """The best Or-opt move at every city ``a`` (or at the cities ``at`` only): (gain, lo, hi,
    kind, span, rev), one per city.

    The segments of 1..:data:`OR_OPT_MAX` cities with ``a`` at one end are moved next to a
    candidate ``c2`` of ``a`` (between ``c2`` and its successor or predecessor, in the
    orientation that makes ``(a, c2)`` an edge): the moves of the don't-look-bit search,
    evaluated at all cities at once. Each move is written on the one of its two equivalent
    position ranges that does not wrap around the tour's end (the segment moved forward to
    its new place, or the rest of the cycle moved behind it); the few moves of a segment that
    straddles the array's end (positions ``n - 1`` and ``0``) have no such range and are
    left out (gain ``-inf``).
    """
    n, k = cand.shape
    if at is not None:  # the rows of the cities ``at`` only
        cand, cand_d, pos_a = cand[at], cand_d[at], pos[at]
    else:
        pos_a = pos
    rows = pos_a.shape[0]
    cities = jnp.arange(rows, dtype=jnp.int32)
    lens = jnp.array([1, 2, 3, 2, 3], jnp.int32)[: 2 * OR_OPT_MAX - 1]
    back = jnp.arange(lens.shape[0]) >= OR_OPT_MAX
    sa = jnp.where(back, pos_a[:, None] - lens + 1, pos_a[:, None]) % n  # (rows, S) start
    first, last = tour[sa], tour[(sa + lens - 1) % n]
    pp, ss = tour[(sa - 1) % n], tour[(sa + lens) % n]
    g_rem = dist[pp, first] + dist[last, ss] - dist[pp, ss]  # (rows, S)
    other = jnp.where(back, first, last)[:, :, None]  # the segment's end away from a
    q = (pos[cand][:, None, :] - sa[:, :, None]) % n  # (rows, S, k): c2 from the segment
    in_seg = q < lens[None, :, None]
    sc, pc = succ[cand][:, None, :], pred[cand][:, None, :]
    dc = cand_d[:, None, :]
    # after c2: c2 - a .. other - succ c2; before c2: pred c2 - other .. a - c2
    g_after = dist[cand, succ[cand]][:, None, :] - dc - dist[other, sc]
    g_before = dist[pred[cand], cand][:, None, :] - dc - dist[pc, other]
    ok_after = ~in_seg & (q != n - 1)  # c2 == pp is the segment's own place
    ok_before = ~in_seg & (q != lens[None, :, None])  # and so is c2 == ss
    g = jnp.stack([jnp.where(ok_after, g_rem[..., None] + g_after, -jnp.inf),
                   jnp.where(ok_before, g_rem[..., None] + g_before, -jnp.inf)], axis=-1)
    flat = jnp.argmax(g.reshape(rows, -1), axis=1).astype(jnp.int32)
    gain = jnp.take_along_axis(g.reshape(rows, -1), flat[:, None], axis=1)[:, 0]
    si, hc, side = flat // (2 * k), (flat // 2) % k, flat % 2
    span, start = lens[si], sa[cities, si]
    t = q[cities, si, hc] - side  # insert after relative position t, span <= t <= n - 2
    # forward segment (a first): after c2 keeps its order, before c2 reverses it; backward
    # segment (a last): the other way round
    rev = jnp.where(back[si], side == 0, side == 1)
    forward = start + t <= n - 1  # [start, start + t]: the segment goes to the range's end
    lo = jnp.where(forward, start, start + t + 1 - n)  # else the rest goes behind it
    hi = jnp.where(forward, start + t, start + span - 1)
    kind = jnp.where(forward, SEGMENT_TO_END, SEGMENT_TO_FRONT)
    gain = jnp.where(hi <= n - 1, gain, -jnp.inf)  # a segment across the array's end
    return gain, lo, hi, kind, span, rev


def _two_opt_moves(pos: Array, succ: Array, pred: Array, dist: Array, cand: Array,
                   cand_d: Array, at: Array | None = None) -> tuple[Array, Array, Array]:
    """The best 2-opt move at every city ``a`` (or at the cities ``at`` only): (gain, lo, hi),
    the move reversing positions ``[lo, hi]`` (never wrapping the array's end), gain
    ``-inf`` where no move improves."""
    n = pos.shape[0]
    a = jnp.arange(n, dtype=jnp.int32) if at is None else at
    cand, cand_d = (cand, cand_d) if at is None else (cand[at], cand_d[at])
    rows = jnp.arange(a.shape[0])
    if at is None:  # d(x, succ x) of every city, once (O(n)), then gathered
        d_succ = dist[a, succ]

        def ds(x):
            return d_succ[x]
    else:  # ... only of the cities a focused step reads (O(width k))
        def ds(x):
            return dist[x, succ[x]]
    sa, pa = succ[a], pred[a]
    sc, pc = succ[cand], pred[cand]
    degenerate = (cand == sa[:, None]) | (cand == pa[:, None])
    g_s = ds(a)[:, None] + ds(cand) - cand_d - dist[sa[:, None], sc]
    g_p = ds(pa)[:, None] + ds(pc) - cand_d - dist[pa[:, None], pc]
    g_s = jnp.where(degenerate, -jnp.inf, g_s)
    g_p = jnp.where(degenerate, -jnp.inf, g_p)
    js, jp = jnp.argmax(g_s, axis=1), jnp.argmax(g_p, axis=1)
    gs = jnp.take_along_axis(g_s, js[:, None], axis=1)[:, 0]
    gp = jnp.take_along_axis(g_p, jp[:, None], axis=1)[:, 0]
    use_pred = gp > gs
    gain = jnp.maximum(gs, gp)
    c = jnp.where(use_pred, cand[rows, jp], cand[rows, js])
    i, j = pos[a], pos[c]
    lo, hi = jnp.minimum(i, j), jnp.maximum(i, j)
    # successor move reverses (lo, hi]; predecessor move reverses [lo, hi)
    lo = jnp.where(use_pred, lo, lo + 1)
    hi = jnp.where(use_pred, hi - 1, hi)
    # reversing [0, hi] == reversing the complement [hi + 1, n - 1]: no wrap-around arcs
    wrap = lo == 0
    lo, hi = jnp.where(wrap, hi + 1, lo), jnp.where(wrap, n - 1, hi)
    return jnp.where(gain > 0, gain, -jnp.inf), lo, hi


def _apply_proposals(tour: Array, pos: Array, two: tuple[Array, Array, Array],
                     orr: tuple[Array, ...] | None, per_step: int, budget: Array,
                     acceptance: str, ends: bool = False) -> tuple[Array, ...]:
    """Apply the best disjoint of a step's proposals: ``two`` = (gain, lo, hi) of 2-opt
    reversals, and with ``orr`` = (gain, lo, hi, kind, span, rev) of Or-opt moves competing
    in the same batch (gains ``-inf`` where nothing improves); see :func:`_apply_disjoint`."""
    gain, lo, hi = two
    if orr is None:
        return _apply_disjoint(tour, pos, gain, lo, hi, per_step, budget, acceptance=acceptance,
                               ends=ends)
    og, olo, ohi, okind, ospan, orev = orr
    m = gain.shape[0]
    return _apply_disjoint(
        tour, pos, jnp.concatenate([gain, og]), jnp.concatenate([lo, olo]),
        jnp.concatenate([hi, ohi]), per_step, budget,
        kind=jnp.concatenate([jnp.full(m, REVERSE, jnp.int32), okind]),
        span=jnp.concatenate([jnp.zeros(m, jnp.int32), ospan]),
        rev=jnp.concatenate([jnp.zeros(m, bool), orev]), acceptance=acceptance, ends=ends)


class _Beside:
    """The successor (``step`` 1) or predecessor (-1) of the cities it is indexed with, read
    from (tour, pos) for those cities only: a focused step reads O(width k) of them, not the
    O(n) array of every city's."""

    def __init__(self, tour: Array, pos: Array, step: int) -> None:
        self.tour, self.pos, self.step = tour, pos, step

    def __getitem__(self, x: Array) -> Array:
        return self.tour[(self.pos[x] + self.step) % self.tour.shape[0]]


def _focused_fns(dist: Array, cand: Array, cand_d: Array, max_moves: int, per_step: int,
                 or_opt: bool, acceptance: str, width: int, n: int):
    """(body, live) of one tour's focused search (:func:`_focused`): a step on the carry
    ``(tour, pos, active, at, count, moves, steps)``, and whether the search goes on. ``at``
    and ``count`` are :func:`first_true` of ``active`` (the cities the next step evaluates,
    and how many bits are set), found at the end of the step that set the bits: the test
    whether the search goes on reads ``count`` instead of reducing all ``n`` bits again.
    ``active`` may be longer than ``n`` (False past ``n``; :func:`_focused` makes it
    :func:`~eaco_jax.ops.compaction.blocks_of` ``n`` long, which :func:`first_true` sums
    without padding it every step)."""
    slots = jnp.arange(width)

    def body(carry):
        tour, pos, active, at, count, moves, steps = carry
        succ, pred = _Beside(tour, pos, 1), _Beside(tour, pos, -1)
        valid = slots < count
        gain, lo, hi = _two_opt_moves(pos, succ, pred, dist, cand, cand_d, at)
        gain = jnp.where(valid, gain, -jnp.inf)
        found = gain > 0
        orr = None
        if or_opt:
            og, *rest = _or_opt_moves(tour, pos, succ, pred, dist, cand, cand_d, at)
            og = jnp.where(valid & (og > 0), og, -jnp.inf)
            found = found | (og > 0)
            orr = (og, *rest)
        new_tour, new_pos, applied, cut = _apply_proposals(
            tour, pos, (gain, lo, hi), orr, per_step, max_moves - moves, acceptance, ends=True)
        none = active.shape[0]  # an index past the bits: the scatters below drop it
        # evaluated, nothing to gain: bit cleared (the padding slots touch nothing)
        active = active.at[jnp.where(valid & ~found, at, none)].set(False, mode="drop")
        # of the ends of every removed edge, the cities whose pair of tour neighbours changed
        # (no other city's can): bit set
        c = jnp.minimum(cut, n - 1)
        s0, p0 = succ[c], pred[c]
        s1, p1 = _Beside(new_tour, new_pos, 1)[c], _Beside(new_tour, new_pos, -1)[c]
        same = ((s1 == s0) & (p1 == p0)) | ((s1 == p0) & (p1 == s0))
        active = active.at[jnp.where(same | (cut >= n), none, cut)].set(True, mode="drop")
        at, count = first_true(active, width, 0)  # (jnp.nonzero contends on a GPU)
        return new_tour, new_pos, active, at, count, moves + applied, steps + 1

    def live(carry):
        count, moves = carry[4], carry[5]
        return (count > 0) & (moves < max_moves)

    return body, live


def _vmapped_steps(body, live, carry: tuple[Array, ...], most: int | None = None
                   ) -> tuple[Array, ...]:
    """Every ant's focused search as a vmapped ``while_loop``, one per ant (each at most
    ``most`` steps; None: until it is done)."""
    go_on = live if most is None else (lambda x: live(x) & (x[-1] < most))
    return jax.vmap(lambda x: jax.lax.while_loop(go_on, body, x))(carry)


def _colony_steps(body, live, carry: tuple[Array, ...], most: int | None = None
                  ) -> tuple[Array, ...]:
    """Every ant's focused search as one loop over the colony's steps (at most ``most`` of
    them; None: until every ant is done): a vmapped ``while_loop`` (:func:`_vmapped_steps`)
    selects, after every step, each ant's whole carry (its (n,) tour, positions and bits)
    between the old and the new, so that ants already done keep theirs. Here a done ant's
    step changes no tour, positions or move count anyway (no active city, or no moves left to
    apply; an ant stopped by the move cap may still clear bits, which nothing reads after), so
    the step runs for every ant without that select, and only the step count is kept per ant.
    Stopped after ``most`` steps, every ant still searching has run exactly ``most``."""

    def step(state):
        carry, alive, t = state
        stepped = jax.vmap(body)(carry)  # the step count (last) is kept per ant
        carry = stepped[:-1] + (carry[-1] + alive.astype(jnp.int32),)
        return carry, jax.vmap(live)(carry), t + 1

    def go_on(state):
        more = jnp.any(state[1])
        return more if most is None else more & (state[2] < most)

    carry, _, _ = jax.lax.while_loop(go_on, step, (carry, jax.vmap(live)(carry), jnp.int32(0)))
    return carry


#: the step loops of :data:`LOOPS`
_STEPS = {"ants": _vmapped_steps, "colony": _colony_steps}


def _focused(
    tours: Array, active0: Array, dist: Array, cand: Array, cand_d: Array, max_moves: int,
    per_step: int, or_opt: bool, acceptance: str, width: int, loop: str,
    compact: tuple[int, int] | None,
) -> tuple[Array, Array, Array]:
    """The batched search of every tour from the cities ``active0`` only (don't-look bits, as
    Focused ACO searches an ant that changed a few edges of the best tour): each step
    evaluates the moves of at most ``width`` active cities (the first in index order), not of
    all ``n``; applies the best disjoint improving ones as :func:`_two_opt_one` does; clears
    the bit of every evaluated city without an improving move and sets the bits of both ends
    of every edge the step removed. A tour's search ends when no bit is set (or after
    ``max_moves``): a tour that is a local optimum except near a few changed edges costs
    O(width k) a step instead of O(n k), plus the O(n) rewrite of the tour. ``loop`` picks the
    step loop (:data:`_STEPS`); ``compact`` = ``(first_steps, batch)``: every ant runs at most
    ``first_steps`` steps, then the ants still searching go on ``batch`` at a time
    (unfinished first), each batch until its last ant is done, so that the colony does not
    wait for its slowest ant. The same tours, moves and steps whatever the loop and
    compaction. Returns (tours, moves, steps)."""
    m, n = tours.shape
    body, live = _focused_fns(dist, cand, cand_d, max_moves, per_step, or_opt, acceptance,
                              width, n)
    steps = _STEPS[loop]
    cities = jnp.arange(n, dtype=jnp.int32)
    pos0 = jax.vmap(lambda t: jnp.zeros(n, jnp.int32).at[t].set(cities))(tours)
    zeros = jnp.zeros((m,), jnp.int32)
    active0 = jnp.pad(jnp.asarray(active0, bool), ((0, 0), (0, blocks_of(n) - n)))
    at0, count0 = jax.vmap(lambda a: first_true(a, width, 0))(active0)
    carry = (tours, pos0, active0, at0, count0, zeros, zeros)
    if compact is None:
        carry = steps(body, live, carry)
        return carry[0], carry[-2], carry[-1]
    first_steps, batch = compact
    batch = min(int(batch), m)
    carry = steps(body, live, carry, first_steps)
    still = jax.vmap(live)(carry)
    order = jnp.argsort(~still, stable=True).astype(jnp.int32)  # unfinished ants first
    count = jnp.sum(still)

    def chunk(state):
        c, carry = state
        # a start past m - batch is clamped: the overlap holds finished ants, left as they are
        ids = jax.lax.dynamic_slice(order, (c * batch,), (batch,))
        sub = steps(body, live, jax.tree_util.tree_map(lambda x: x[ids], carry))
        carry = jax.tree_util.tree_map(lambda x, y: x.at[ids].set(y), carry, sub)
        return c + 1, carry

    _, carry = jax.lax.while_loop(lambda st: st[0] * batch < count, chunk,
                                  (jnp.int32(0), carry))
    return carry[0], carry[-2], carry[-1]


def _two_opt_one(
    tour: Array,
    dist: Array,
    cand: Array,
    cand_d: Array,
    max_moves: int,
    per_step: int,
    or_opt: bool = False,
    acceptance: str = "rounds",
) -> tuple[Array, Array, Array]:
    """2-opt (and Or-opt) of one tour with candidate lists (see module docstring):
    (tour, moves, steps); the focused search is :func:`_focused`."""
    n = tour.shape[0]
    cities = jnp.arange(n, dtype=jnp.int32)
    pos0 = jnp.zeros(n, jnp.int32).at[tour].set(cities)

    def body(carry):
        tour, pos, moves, steps, _ = carry
        succ = tour[(pos + 1) % n]  # successor of each city
        pred = tour[(pos - 1) % n]
        gain, lo, hi = _two_opt_moves(pos, succ, pred, dist, cand, cand_d)
        orr = None
        if or_opt:  # each city's best 2-opt move and its best Or-opt move compete
            og, *rest = _or_opt_moves(tour, pos, succ, pred, dist, cand, cand_d)
            orr = (jnp.where(og > 0, og, -jnp.inf), *rest)
        tour, pos, applied = _apply_proposals(tour, pos, (gain, lo, hi), orr, per_step,
                                              max_moves - moves, acceptance)
        return tour, pos, moves + applied, steps + 1, applied == 0

    def cond(carry):
        _, _, moves, _, done = carry
        return (~done) & (moves < max_moves)

    zero = jnp.int32(0)
    tour, _, moves, steps, _ = jax.lax.while_loop(
        cond, body, (tour, pos0, zero, zero, jnp.bool_(False))
    )
    return tour, moves, steps


@partial(jax.jit, static_argnames=("max_moves", "return_moves", "moves_per_step", "or_opt",
                                   "return_steps", "acceptance", "focus_width", "compact",
                                   "loop"))
def two_opt(
    tours: Array,
    dist: Array,
    neighbors: Array | None = None,
    max_moves: int | None = None,
    return_moves: bool = False,
    moves_per_step: int = 32,
    or_opt: bool = False,
    return_steps: bool = False,
    acceptance: str = "rounds",
    active: Array | None = None,
    focus_width: int = 128,
    compact: tuple[int, int] | None = None,
    loop: str = "ants",
) -> Array | tuple[Array, Array] | tuple[Array, Array, Array]:
    """2-opt (and Or-opt) local search of every tour in ``tours`` ``(m, n)`` to a local optimum.

    Args:
      tours: int32 ``(m, n)`` permutations.
      dist: ``(n, n)`` float32 symmetric distances (exact integers for termination safety).
      neighbors: ``(n, k)`` candidate lists (e.g. ``TSP.neighbors``); None = all cities.
      max_moves: cap on improving moves per tour (default ``4 n``).
      return_moves: also return the number of moves applied per tour ``(m,)`` int32.
      moves_per_step: most moves applied per step (1 = best improvement; see module doc).
      or_opt: also Or-opt moves (segments of 1..3 cities moved next to a candidate; see
        :func:`_or_opt_moves`), competing with the 2-opt moves in every step.
      return_steps: return ``(tours, moves, steps)``: also the improvement steps each tour's
        loop ran ``(m,)`` int32 (the vmapped loop runs as many as the largest; this is what a
        benchmark of ``moves_per_step`` counts).
      acceptance: how a step accepts its disjoint moves, :data:`ACCEPTANCES` (the same tours
        either way; "sequential" is the one-by-one reference, kept to time against).
      active: ``(m, n)`` bool, search from these cities only, with don't-look bits
        (:func:`_focused`; Focused ACO: the ends of the edges an ant changed,
        :func:`changed_cities`). None: every city, every step.
      focus_width: with ``active``, the most cities a step evaluates.
      compact: with ``active``, ``(first_steps, batch)``: the same search without the colony
        waiting for its slowest ant (:func:`_focused`); None: one loop.
      loop: with ``active``, :data:`LOOPS`: "ants" (a vmapped loop, one per tour) or
        "colony" (one loop over the colony's steps, :func:`_colony_steps`), also for each
        of ``compact``'s batches; the same tours, moves and steps either way.
    Returns:
      improved int32 tours ``(m, n)``, each no longer than its input.
    """
    if acceptance not in ACCEPTANCES:
        raise ConfigError(f"acceptance={acceptance!r} is not one of {ACCEPTANCES}")
    if loop not in LOOPS:
        raise ConfigError(f"loop={loop!r} is not one of {LOOPS}")
    tours = jnp.asarray(tours, jnp.int32)
    dist = as_distances(dist)
    _check(tours, dist, neighbors, or_opt)
    cand = _candidates(dist, neighbors)
    cand_d = dist[jnp.arange(dist.shape[0])[:, None], cand]
    m, n = tours.shape
    mm = _default_max_moves(n, max_moves)
    if active is None:
        out, moves, steps = jax.vmap(
            lambda t: _two_opt_one(t, dist, cand, cand_d, mm, moves_per_step, or_opt,
                                   acceptance))(tours)
    else:
        active = jnp.asarray(active, bool)
        if active.shape != (m, n):
            raise ValueError(f"active must have the tours' shape {(m, n)}, got {active.shape}")
        if focus_width < 1:
            raise ConfigError(f"focus_width must be >= 1, got {focus_width}")
        width = min(int(focus_width), n)
        if compact is not None:
            compact = tuple(int(x) for x in compact)
            if compact[0] < 0 or compact[1] < 1:
                raise ConfigError(f"compact=(first_steps, batch) needs first_steps >= 0 and "
                                  f"batch >= 1, got {compact}")
        out, moves, steps = _focused(tours, active, dist, cand, cand_d, mm, moves_per_step,
                                     or_opt, acceptance, width, loop, compact)
    if return_steps:
        return out, moves, steps
    return (out, moves) if return_moves else out


# --------------------------------------------------------------------------------------------
# ACOTSP-style local search: first improvement over candidate lists with don't-look bits,
# optionally followed by Or-opt segment moves. One move per loop iteration and tour. On a CPU
# the same search runs as native code (local_search_native.py; identical tours).
# --------------------------------------------------------------------------------------------
def _shorter_side(n: int, a: Array, length: Array) -> tuple[Array, Array]:
    """(start, length) of the side to reverse when reversing the cyclic segment of ``length``
    positions from position ``a``: the segment, or its complement when that is shorter (the
    same cycle; ACOTSP reverses the shorter side)."""
    inner = length <= n - length
    return jnp.where(inner, a, (a + length) % n), jnp.where(inner, length, n - length)


def _move_positions(
    n: int, base: Array, kind: Array, span: Array, t: Array, rev: Array
) -> tuple[Array, Array]:
    """Relative source index of every new relative position, and new relative position of every
    old relative position, for one move in coordinates relative to ``base``.

    ``kind`` 0: no move; 1: reverse relative positions ``[0, span)``; 2: Or-opt, move the
    segment ``[0, span)`` to just after relative position ``t`` (``span <= t <= n - 2``),
    reversed when ``rev``. Both are elementwise in the position index (O(n), no scatter).
    """
    q = jnp.arange(n, dtype=jnp.int32)
    # reversal: q -> span - 1 - q inside the segment (an involution: src == dst)
    rev_map = jnp.where(q < span, span - 1 - q, q)
    # Or-opt: new order R[span..t], segment, R[t+1..]
    lo = t - span + 1  # first new position of the segment
    seg_src = jnp.where(rev, span - 1 - (q - lo), q - lo)
    or_src = jnp.where(q <= t - span, q + span, jnp.where(q <= t, seg_src, q))
    seg_dst = lo + jnp.where(rev, span - 1 - q, q)
    or_dst = jnp.where(q < span, seg_dst, jnp.where(q <= t, q - span, q))
    src = jnp.where(kind == 1, rev_map, jnp.where(kind == 2, or_src, q))
    dst = jnp.where(kind == 1, rev_map, jnp.where(kind == 2, or_dst, q))
    return src, dst


def _apply_move(tour: Array, pos: Array, base: Array, src: Array, dst: Array):
    """New (tour, pos) after a move given by relative maps (see :func:`_move_positions`)."""
    n = tour.shape[0]
    p = jnp.arange(n, dtype=jnp.int32)
    new_tour = tour[(base + src[(p - base) % n]) % n]
    new_pos = (base + dst[(pos - base) % n]) % n
    return new_tour, new_pos


def _first_true(mask: Array) -> tuple[Array, Array]:
    """(index of the first True, whether any)."""
    return jnp.argmax(mask).astype(jnp.int32), jnp.any(mask)


def _dlb_one(
    tour: Array,
    order: Array,
    dist: Array,
    cand: Array,
    cand_d: Array,
    max_moves: int,
    or_opt: bool,
    full_check: bool,
    block: int = 1,
    active0: Array | None = None,
) -> tuple[Array, Array, Array]:
    """Don't-look-bit local search of one tour: (tour, moves, loop iterations).

    Cities are visited in the cyclic order ``order`` (a permutation of cities), skipping those
    whose don't-look bit is set. For city ``c1`` with successor ``s1`` and predecessor ``p1``:

    * 2-opt, successor side (ACOTSP's ``two_opt_first``): scan ``c1``'s candidates ``c2`` in
      list order while ``d(c1, c2) < d(c1, s1)``; the first with a positive gain
      ``d(c1,s1) + d(c2,s2) - d(c1,c2) - d(s1,s2)`` (``s2 = succ c2``) is applied. Then the
      predecessor side likewise. The shorter of the two sides is reversed.
    * Or-opt (when ``or_opt`` and no 2-opt move was found): the segments of 1..3 cities that
      start or end at ``c1`` are moved next to a candidate ``c2`` of ``c1`` (between ``c2`` and
      one of its tour neighbours, in the orientation that makes ``(c1, c2)`` an edge), for the
      candidates with ``d(c1, c2)`` below the segment's removal gain ``d(p, first) + d(last,
      s) - d(p, s)`` (the gain criterion, Or-opt's counterpart of the 2-opt radius: it keeps
      the scan to a few near candidates); the move of largest positive gain is applied.
    * A move clears the don't-look bits of the endpoints of every removed edge; no move sets
      ``c1``'s bit. The bits start clear for every city, or where ``active0`` is True only
      (Focused ACO: the cities of the edges an ant changed). The search ends when every bit
      is set (with ``full_check``: and a full pass over all cities found nothing, which makes
      the result a local optimum of the candidate neighbourhood), or after ``max_moves``
      moves.

    Each loop iteration evaluates the next ``block`` cities with clear bits at once and applies
    the first move found among them: the very search of one city per iteration (the same
    moves, in the same order) in fewer, wider iterations.
    """
    n = tour.shape[0]
    k = cand.shape[1]
    cities = jnp.arange(n, dtype=jnp.int32)
    rank = jnp.zeros(n, jnp.int32).at[order].set(cities)
    pos0 = jnp.zeros(n, jnp.int32).at[tour].set(cities)

    def evaluate(c1: Array, tour: Array, pos: Array):
        """The move chosen at city c1: (kind 0/1/2, base, span, t, reversed, 6 endpoints)."""
        i1 = pos[c1]
        s1, p1 = tour[(i1 + 1) % n], tour[(i1 - 1) % n]
        c2s, d12 = cand[c1], cand_d[c1]
        # --- 2-opt, successor then predecessor side (radius-pruned, first improvement)
        s2 = tour[(pos[c2s] + 1) % n]
        rad_s = dist[c1, s1]
        ok_s = jnp.cumprod(d12 < rad_s).astype(bool) & (c2s != p1)
        g_s = rad_s + dist[c2s, s2] - d12 - dist[s1, s2]
        h_s, any_s = _first_true(ok_s & (g_s > 0))
        p2 = tour[(pos[c2s] - 1) % n]
        rad_p = dist[p1, c1]
        ok_p = jnp.cumprod(d12 < rad_p).astype(bool) & (c2s != s1)
        g_p = rad_p + dist[p2, c2s] - d12 - dist[p1, p2]
        h_p, any_p = _first_true(ok_p & (g_p > 0))
        two = any_s | any_p
        c2 = jnp.where(any_s, c2s[h_s], c2s[h_p])
        # successor side: reverse s1..c2; predecessor side: reverse c1..p2
        a = jnp.where(any_s, pos[s1], i1)
        b = jnp.where(any_s, pos[c2], pos[p2[h_p]])
        base2, span2 = _shorter_side(n, a, (b - a) % n + 1)
        ends2 = jnp.stack([c1, jnp.where(any_s, s1, p1), c2,
                           jnp.where(any_s, s2[h_s], p2[h_p])])
        kind = jnp.where(two, 1, 0)
        base, span, t, rv = base2, span2, jnp.int32(0), jnp.bool_(False)
        ends = jnp.concatenate([ends2, ends2[:2]])
        if or_opt:
            # segments: forward [c1 .. c1+L-1] (c1 first) and backward [c1-L+1 .. c1] (c1
            # last), L = 1..3 (L = 1 only once); sa = start position, c1 at one end
            lens = jnp.array([1, 2, 3, 2, 3], jnp.int32)[: 2 * OR_OPT_MAX - 1]
            back = jnp.arange(lens.shape[0]) >= OR_OPT_MAX
            sa = jnp.where(back, i1 - lens + 1, i1) % n
            first, last = tour[sa], tour[(sa + lens - 1) % n]
            pp, ss = tour[(sa - 1) % n], tour[(sa + lens) % n]
            g_rem = dist[pp, first] + dist[last, ss] - dist[pp, ss]  # (S,)
            # the other end of each segment (away from c1)
            other = jnp.where(back, first, last)
            qc2 = (pos[c2s][None, :] - sa[:, None]) % n  # (S, k) relative position of c2
            in_seg = qc2 < lens[:, None]
            succ_c2 = tour[(pos[c2s] + 1) % n]
            pred_c2 = tour[(pos[c2s] - 1) % n]
            # after c2: c2 - c1 .. other - succ(c2); before c2: pred(c2) - other .. c1 - c2
            g_after = (dist[c2s, succ_c2][None, :] - d12[None, :]
                       - dist[other[:, None], succ_c2[None, :]])
            g_before = (dist[pred_c2, c2s][None, :] - d12[None, :]
                        - dist[pred_c2[None, :], other[:, None]])
            # the gain criterion: the new edge (c1, c2) shorter than the removed edges' gain
            fits = d12[None, :] < g_rem[:, None]
            ok_after = fits & ~in_seg & (qc2 != n - 1)  # c2 != pp (the segment's own place)
            ok_before = fits & ~in_seg & (qc2 != lens[:, None])  # c2 != ss
            g_or = jnp.stack([jnp.where(ok_after, g_rem[:, None] + g_after, -jnp.inf),
                              jnp.where(ok_before, g_rem[:, None] + g_before, -jnp.inf)],
                             axis=-1)  # (S, k, 2)
            flat = jnp.argmax(g_or.reshape(-1)).astype(jnp.int32)
            best_or = g_or.reshape(-1)[flat]
            si, hi, side = flat // (2 * k), (flat // 2) % k, flat % 2
            do_or = ~two & (best_or > 0)
            oc2 = c2s[hi]
            # insert after relative position t: after c2 -> t = q(c2); before c2 -> q(c2) - 1
            t_or = qc2[si, hi] - side
            # forward segment (c1 first): after c2 keeps order, before c2 reverses;
            # backward segment (c1 last): after c2 reverses, before c2 keeps order
            rv_or = jnp.where(back[si], side == 0, side == 1)
            nb = jnp.where(side == 0, succ_c2[hi], pred_c2[hi])
            ends_or = jnp.stack([pp[si], ss[si], first[si], last[si], oc2, nb])
            kind = jnp.where(do_or, 2, kind)
            base = jnp.where(do_or, sa[si], base)
            span = jnp.where(do_or, lens[si], span)
            t, rv = jnp.where(do_or, t_or, t), jnp.where(do_or, rv_or, rv)
            ends = jnp.where(do_or, ends_or, ends)
        return kind, base, span, t, rv, ends

    blk_size = min(block, n)
    slots = jnp.arange(blk_size)

    def body(carry):
        tour, pos, active, ptr, moves, iters, dirty = carry
        # the next blk_size cities with a clear bit, in cyclic order from ptr, all evaluated on
        # the current tour: until the first of them that moves, the one-by-one search would
        # find the same nothing (the tour does not change), so this is the same search
        if blk_size == 1:
            c1 = jnp.argmin(jnp.where(active, (rank - ptr) % n, n)).astype(jnp.int32)
            blk, valid = c1[None], active[c1][None]
        else:  # the blk_size nearest active cities along the order (tested move for move)
            neg, blk = jax.lax.top_k(-jnp.where(active, (rank - ptr) % n, n), blk_size)
            valid = neg > -n
        kind, base, span, t, rv, ends = jax.vmap(evaluate, (0, None, None))(blk, tour, pos)
        j, moved = _first_true(valid & (kind > 0))
        done = valid & (slots < jnp.where(moved, j, blk_size))  # searched, nothing found
        active = active.at[blk].set(active[blk] & ~done, unique_indices=True)
        kind = jnp.where(moved, kind[j], 0)
        src, dst = _move_positions(n, base[j], kind, span[j], t[j], rv[j])
        tour, pos = _apply_move(tour, pos, base[j], src, dst)
        active = jnp.where(moved, active.at[ends[j]].set(True), active)
        dirty = dirty | moved
        if full_check:  # all bits set after a pass with moves: one more full pass
            again = ~jnp.any(active) & dirty
            active = active | again
            dirty = dirty & ~again
        last = jnp.where(moved, blk[j], blk[jnp.sum(valid) - 1])
        ptr = (rank[last] + 1) % n
        return tour, pos, active, ptr, moves + moved.astype(jnp.int32), iters + 1, dirty

    def cond(carry):
        _, _, active, _, moves, _, _ = carry
        return jnp.any(active) & (moves < max_moves)

    zero = jnp.int32(0)
    start = jnp.ones(n, bool) if active0 is None else jnp.asarray(active0, bool)
    init = (tour, pos0, start, zero, zero, zero, jnp.bool_(False))
    tour, _, _, _, moves, iters, _ = jax.lax.while_loop(cond, body, init)
    return tour, moves, iters


#: implementations of :func:`dlb_local_search`: "xla" (a vmapped ``lax.while_loop``, any
#: backend), "native" (numba machine code called from the jitted step, CPU; identical tours),
#: "auto" (native on a CPU backend, xla elsewhere)
DLB_IMPLS = ("auto", "xla", "native")


def resolve_dlb_impl(impl: str) -> str:
    """"xla" or "native" for ``impl`` on the default backend (see :data:`DLB_IMPLS`)."""
    if impl not in DLB_IMPLS:
        raise ValueError(f"impl={impl!r} is not one of {DLB_IMPLS}")
    if impl == "auto":
        return "native" if jax.default_backend() == "cpu" else "xla"
    return impl


@partial(jax.jit, static_argnames=("max_moves", "return_moves", "or_opt", "full_check",
                                   "block", "impl"))
def dlb_local_search(
    key: Array | None,
    tours: Array,
    dist: Array,
    neighbors: Array | None = None,
    max_moves: int | None = None,
    or_opt: bool = False,
    full_check: bool = False,
    return_moves: bool = False,
    order: Array | None = None,
    block: int = 1,
    impl: str = "auto",
    active: Array | None = None,
) -> Array | tuple[Array, Array]:
    """ACOTSP-style 2-opt (and optionally Or-opt) of every tour ``(m, n)``, see :func:`_dlb_one`.

    Args:
      key: PRNG key for each tour's random city order (ACOTSP's ``random_vector``); None: the
        identity order (or ``order``).
      tours: int32 ``(m, n)`` permutations.
      dist: ``(n, n)`` float32 symmetric distances.
      neighbors: ``(n, k)`` candidate lists sorted nearest first; None = all cities.
      max_moves: cap on improving moves per tour (default ``4 n``).
      or_opt: also try Or-opt segment moves (1-3 cities) when no 2-opt move improves.
      full_check: end only after a full pass without moves (a true candidate-list optimum).
      return_moves: also return the number of moves per tour.
      order: ``(m, n)`` explicit city orders (overrides ``key``; for tests).
      block: cities evaluated per loop iteration (the result does not depend on it; xla only).
      impl: "auto", "xla" or "native" (:data:`DLB_IMPLS`; every one returns the same tours).
        Native is ACOTSP's speed on a CPU: one sequential search per tour is what a CPU does
        well and what XLA's CPU loop does slowly (``eaco_jax/ops/local_search_native.py``).
      active: ``(m, n)`` bool, the cities whose don't-look bits start clear (None: all).
        Focused ACO searches from the endpoints of the edges an ant changed only
        (:func:`changed_cities`): a tour that differs from a local optimum in a few edges
        is searched in a few steps instead of a pass over all ``n`` cities.
    Returns:
      improved int32 tours ``(m, n)``, each no longer than its input.
    """
    tours = jnp.asarray(tours, jnp.int32)
    dist = as_distances(dist)
    _check(tours, dist, neighbors, or_opt)
    m, n = tours.shape
    cand = _candidates(dist, neighbors)
    cand_d = dist[jnp.arange(n)[:, None], cand]
    mm = _default_max_moves(n, max_moves)
    if order is None:
        if key is None:
            order = jnp.broadcast_to(jnp.arange(n, dtype=jnp.int32), (m, n))
        else:
            keys = jax.random.split(key, m)
            order = jax.vmap(lambda kk: jax.random.permutation(kk, n))(keys).astype(jnp.int32)
    order = jnp.asarray(order, jnp.int32)
    if active is None:
        active = jnp.ones((m, n), bool)
    active = jnp.asarray(active, bool)
    if active.shape != (m, n):
        raise ValueError(f"active must have the tours' shape {(m, n)}, got {active.shape}")
    native_mode = _native_mode(dist)
    if resolve_dlb_impl(impl) == "native" and native_mode is not None:
        from eaco_jax.ops.local_search_native import dlb_native

        table = dist.coords if native_mode else dist
        out, moves = dlb_native(tours, order, table, cand, cand_d, mm, or_opt, full_check,
                                native_mode, active)
        return (out, moves) if return_moves else out

    def one(t, o, a):
        return _dlb_one(t, o, dist, cand, cand_d, mm, or_opt, full_check, block, a)

    out, moves, _ = jax.vmap(one)(tours, order, active)
    return (out, moves) if return_moves else out


def _native_mode(dist: Any) -> int | None:
    """The native search's distance mode for ``dist`` (``local_search_native.MODES``), None
    where it has none (coordinates in float32: the XLA search runs them)."""
    if not getattr(dist, "on_the_fly", False):
        return 0
    if getattr(dist, "exact", False) and dist.metric in ("EUC_2D", "CEIL_2D", "ATT"):
        return {"EUC_2D": 1, "CEIL_2D": 2, "ATT": 3}[dist.metric]
    return None


def changed_cities(tours: Array, ref: Array) -> Array:
    """``(m, n)`` bool: the cities of ``tours`` ``(m, n)`` on an edge that the tour ``ref``
    ``(n,)`` does not have (both ends of every such edge), in either direction."""
    tours = jnp.asarray(tours, jnp.int32)
    ref = jnp.asarray(ref, jnp.int32)
    n = ref.shape[0]
    succ = jnp.zeros(n, jnp.int32).at[ref].set(jnp.roll(ref, -1))
    pred = jnp.zeros(n, jnp.int32).at[ref].set(jnp.roll(ref, 1))
    nxt = jnp.roll(tours, -1, axis=1)
    new = (succ[tours] != nxt) & (pred[tours] != nxt)  # edge (tours[:, i], tours[:, i+1])
    rows = jnp.arange(tours.shape[0])[:, None]
    mask = jnp.zeros(tours.shape, bool)
    mask = mask.at[rows, tours].max(new)
    return mask.at[rows, nxt].max(new)


def best_k(tours: Array, lengths: Array, k: int | None, improve, *extra: Array) -> Array:
    """Apply ``improve(tours, *extra) -> tours`` to the ``k`` shortest tours only (all when
    None or ``k >= m``); the others are returned unchanged. ``extra``: per-tour arrays
    ``(m, ...)`` taken along with the tours. Static shapes: ``k`` is a Python int."""
    tours = jnp.asarray(tours, jnp.int32)
    m = tours.shape[0]
    if k is None or k >= m:
        return improve(tours, *extra)
    _, idx = jax.lax.top_k(-lengths, k)
    return tours.at[idx].set(improve(tours[idx], *(e[idx] for e in extra)),
                             unique_indices=True)
