"""Focused construction as moves: each ant is the reference tour changed by a few 2-opt moves.

Focused ACO's ant copies the reference (best) tour except for a bounded number of new edges,
yet :func:`eaco_jax.ops.construction_sparse.construct_tours_sparse` still walks all n
positions one step at a time. Here an ant starts from the reference tour and applies
``n_moves`` 2-opt moves; each inserts one chosen edge (c, v), v drawn from c's candidate list
by the colony's rule (Eq. 2 on the choice weights, the q0 greedy rule), and reverses the
segment between them so the tour stays a permutation (the move also creates the edge between
the two cities that lost c and v). v is drawn among c's candidates that are not its tour
neighbours (``skip_neighbours``), so every move changes the tour, as each of Focused ACO's ants
adds its quota of new edges (its ant follows reference edges between them); drawing a tour
neighbour would be a no-op, and once the trails favour the reference tour almost every draw
would be one.

Sequential depth is ``n_moves`` (a ``fori_loop``), never n: one move is a gather and a select
over each ant's (n,) tour and position arrays, wide and cheap on a GPU.

Where c comes from (``walk``): with ``walk=True`` the ant walks like a constructing ant, c of a
move is the v of the previous one (the first c uniform), and the move removes the edge of c
that it did not arrive by, so the moves chain into one connected change (as the steps of
Lin-Kernighan do); a single 2-opt move at a random place is what a 2-opt local search undoes
first, a chain is not. ``walk=False``: every c uniform, each move on a random side of c.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from eaco_jax.ops.compaction import prefix_sum
from eaco_jax.ops.construction import _sample
from eaco_jax.ops.construction_sparse import candidate_rows

Array = jax.Array

#: how :func:`construct_tours_moves` holds an ant's tour between moves (the same tours)
PLANS = ("arrays", "pieces")


def _reverse(tour: Array, pos: Array, i: Array, d: Array, a: Array, b: Array
             ) -> tuple[Array, Array]:
    """Reverse, per ant, the cyclic stretch of positions ``i + d * a .. i + d * b`` (offsets
    ``a <= b`` from position ``i`` in direction ``d = +-1``; empty if ``a > b``): ``tour``
    (m, n) and its inverse ``pos``, elementwise."""
    n = tour.shape[1]
    i, d, a, b = i[:, None], d[:, None], a[:, None], b[:, None]

    def mapped(p: Array) -> Array:
        rel = (d * (p - i)) % n
        return jnp.where((rel >= a) & (rel <= b), (i + d * (a + b - rel)) % n, p)

    places = jnp.broadcast_to(jnp.arange(n, dtype=jnp.int32)[None, :], tour.shape)
    return jnp.take_along_axis(tour, mapped(places), axis=1), mapped(pos)


class _Pieces:
    """One ant's tour as the reference tour under a piecewise map of positions, for the
    moves of :func:`construct_tours_moves` with ``plan="pieces"``.

    Piece ``j`` sends the reference positions ``dlo[j] .. dhi[j]`` to the positions
    ``(s[j] + g[j] * p) % n`` (``g = +-1``; a piece with ``dlo > dhi`` is empty). The reference
    tour is one piece; a reversal of a stretch of the current tour splits at most two pieces
    at its ends and reflects the pieces inside, so after ``t`` moves there are at most
    ``2 t + 1``, and a move costs O(pieces) per ant instead of a pass over its n positions.
    Methods are per ant (``vmap``-ed by the caller); arrays hold ``2 n_moves + 1`` slots."""

    @staticmethod
    def start(n: int, slots: int) -> tuple[Array, ...]:
        dlo = jnp.full(slots, n, jnp.int32).at[0].set(0)
        dhi = jnp.full(slots, -1, jnp.int32).at[0].set(n - 1)
        return dlo, dhi, jnp.zeros(slots, jnp.int32), jnp.ones(slots, jnp.int32), jnp.int32(1)

    @staticmethod
    def position(state, p: Array, n: int) -> Array:
        """The current position of reference position ``p``."""
        dlo, dhi, s, g, _ = state
        j = jnp.argmax((dlo <= p) & (p <= dhi))
        return (s[j] + g[j] * p) % n

    @staticmethod
    def source(state, q: Array, n: int) -> tuple[Array, Array]:
        """(reference position at current position ``q``, its piece)."""
        dlo, dhi, s, g, _ = state
        p = (g * (q - s)) % n
        j = jnp.argmax((dlo <= p) & (p <= dhi))
        return p[j], j

    @staticmethod
    def cut(state, z: Array, n: int):
        """Split the piece that holds current positions ``z - 1`` and ``z`` between them."""
        dlo, dhi, s, g, count = state
        p, j = _Pieces.source(state, z, n)
        at = jnp.where(g[j] == 1, p, p + 1)  # the first reference position of the new piece
        split = (at > dlo[j]) & (at <= dhi[j])
        slot = jnp.where(split, count, dlo.shape[0])  # out of range: dropped
        dlo = dlo.at[slot].set(at, mode="drop")
        dhi = dhi.at[slot].set(dhi[j], mode="drop")
        s = s.at[slot].set(s[j], mode="drop")
        g = g.at[slot].set(g[j], mode="drop")
        dhi = dhi.at[j].set(jnp.where(split, at - 1, dhi[j]))
        return dlo, dhi, s, g, count + split.astype(jnp.int32)

    @staticmethod
    def reverse(state, x: Array, length: Array, mirror: Array, n: int):
        """Reverse the ``length`` current positions from ``x`` on (cyclic; none if
        ``length < 1``): position ``q`` inside goes to ``(mirror - q) % n``."""
        cut = _Pieces.cut(_Pieces.cut(state, x, n), (x + length) % n, n)
        dlo, dhi, s, g, count = cut
        first = (s + g * dlo) % n  # where each piece's first reference position now lies
        inside = (dlo <= dhi) & ((first - x) % n < length)
        s = jnp.where(inside, (mirror - s) % n, s)
        g = jnp.where(inside, -g, g)
        out = (dlo, dhi, s, g, count)
        return jax.tree_util.tree_map(lambda a, b: jnp.where(length >= 1, a, b), out, state)

    @staticmethod
    def tour(state, ref: Array) -> Array:
        """The current tour: every reference position's city at its current position."""
        dlo, dhi, s, g, _ = state
        n = ref.shape[0]
        first = jnp.where(dlo <= dhi, dlo, n)  # empty slots after every piece
        order = jnp.argsort(first).astype(jnp.int32)
        starts = jnp.zeros(n, jnp.int32).at[first].add(1, mode="drop")
        j = order[prefix_sum(starts, 1) - 1]  # the piece of every reference position
        p = jnp.arange(n, dtype=jnp.int32)
        q = (s[j] + g[j] * p) % n
        return jnp.zeros(n, jnp.int32).at[q].set(ref, unique_indices=True)


def construct_tours_moves(
    key: Array,
    cand_w: Array,
    candidates: Array,
    ref_tour: Array,
    n_moves: int,
    num_ants: int,
    q0: Array | float = 0.0,
    row_offset: Array | None = None,
    factor: Array | None = None,
    walk: bool = True,
    skip_neighbours: bool = True,
    kind: str = "2opt",
    segment: int = 8,
    new_only: bool = False,
    plan: str = "arrays",
) -> Array:
    """One tour per ant: ``ref_tour`` after ``n_moves`` 2-opt moves (module docstring).

    Args:
      key: PRNG key.
      cand_w: (R, k) non-negative choice weights of the candidates (R = n, or stacked
        multiples of n: ant a at city c reads row ``row_offset[a] + c``).
      candidates: (n, k) int32 candidate lists.
      ref_tour: (n,) the tour every ant starts from.
      n_moves: moves per ant (a Python int; 0 returns the reference tour).
      num_ants: m.
      q0: probability of the greedy choice, scalar or (m,).
      row_offset: (m,) multiples of n (default 0).
      factor: optional (m, n) multiplicative perturbation of the weights (chaos).
      walk: chain the moves (c = the previous move's v) instead of a uniform c per move.
      skip_neighbours: draw v among c's candidates that are not its tour neighbours now,
        so every move changes the tour (False: such a draw is a no-op).
      kind: "2opt" (the stretch from c's other neighbour to v reversed: two new edges) or
        "or3opt" (v and up to ``segment`` - 1 cities after it move between c and its
        neighbour: three new edges, a move that one 2-opt or Or-opt step does not undo).
      segment: the longest segment an "or3opt" move carries (its length is uniform in
        1..segment).
      new_only: draw v among c's candidates that are not its neighbours in ``ref_tour``
        either, so that every move inserts an edge the reference lacks. Without it, once the
        trails favour the reference tour, a chain of moves mostly puts back the reference
        edges that its previous moves removed, and many moves leave few changed edges.
      plan: how an ant's tour is held between moves (the same tours either way, see
        :data:`PLANS`): "arrays" rewrites its (n,) tour and positions at every move;
        "pieces" keeps the reference tour under a piecewise map of positions
        (:class:`_Pieces`), O(moves) a move, and writes the tour once at the end.

    Returns:
      (m, n) int32 tours (each a permutation; the start city is not fixed).
    """
    n, k = candidates.shape
    m = int(num_ants)
    cands, q0, row_offset = candidate_rows(cand_w, candidates, m, q0, row_offset)
    if kind not in ("2opt", "or3opt"):
        raise ValueError(f"kind={kind!r} is not one of 2opt, or3opt")
    if n_moves < 0:
        raise ValueError(f"n_moves must be >= 0, got {n_moves}")
    if plan not in PLANS:
        raise ValueError(f"plan={plan!r} is not one of {PLANS}")
    ref = jnp.asarray(ref_tour, jnp.int32)
    tour = jnp.broadcast_to(ref, (m, n))
    pos = jnp.broadcast_to(jnp.zeros(n, jnp.int32).at[ref].set(jnp.arange(n, dtype=jnp.int32)),
                           (m, n))
    if n_moves == 0:
        return tour
    every = jnp.arange(m, dtype=jnp.int32)
    if new_only:  # the reference's neighbours, whose edges a move may not insert
        ref_succ, ref_pred = ref[(pos[0] + 1) % n], ref[(pos[0] - 1) % n]

    if plan == "pieces":  # the reference under a piecewise map of positions (_Pieces)
        refpos = pos[0]
        slots = (2 if kind == "2opt" else 6) * n_moves + 1
        held = jax.vmap(lambda _: _Pieces.start(n, slots))(every)

        def position_of(held, cities):
            return jax.vmap(_Pieces.position, (0, 0, None))(held, refpos[cities], n)

        def city_at(held, places):
            return ref[jax.vmap(_Pieces.source, (0, 0, None))(held, places % n, n)[0]]

        def reverse(held, i, d, a, b):
            x = jnp.where(d == 1, i + a, i - b) % n
            mirror = (2 * i + d * (a + b)) % n
            return jax.vmap(_Pieces.reverse, (0, 0, 0, 0, None))(held, x, b - a + 1, mirror, n)

        def finish(held):
            return jax.vmap(_Pieces.tour, (0, None))(held, ref)
    else:  # every ant's (n,) tour and positions, rewritten at each move
        held = (tour, pos)

        def position_of(held, cities):
            return held[1][every, cities]

        def city_at(held, places):
            return held[0][every, places % n]

        def reverse(held, i, d, a, b):
            return _reverse(held[0], held[1], i, d, a, b)

        def finish(held):
            return held[0]

    def move(t, carry):
        held, cur, came = carry
        # move t's draws from its own key: the first t moves do not depend on n_moves
        k_city, k_pick, k_side, k_len = jax.random.split(jax.random.fold_in(key, t), 4)
        start = jax.random.randint(k_city, (m,), 0, n, jnp.int32)
        side = jax.random.bernoulli(k_side, 0.5, (m,))
        c = start if not walk else jnp.where(t == 0, start, cur)
        cand = cands[c]  # (m, k)
        w = cand_w[row_offset + c]
        w = w if factor is None else w * factor[every[:, None], cand]
        i = position_of(held, c)
        pred_c = city_at(held, i - 1)
        if skip_neighbours:
            succ_c = city_at(held, i + 1)
            w = jnp.where((cand == pred_c[:, None]) | (cand == succ_c[:, None]), 0.0, w)
        if new_only:
            w = jnp.where((cand == ref_pred[c][:, None]) | (cand == ref_succ[c][:, None]), 0.0,
                          w)
        idx, ok = _sample(w, jax.random.uniform(k_pick, (m,)), q0)
        v = jnp.where(ok, cand[every, idx], c)  # no positive weight: no move
        # the side of c whose edge goes: walking, not the edge the ant arrived by
        after = side if not walk else jnp.where(t == 0, side, came == pred_c)
        d = jnp.where(after, 1, -1).astype(jnp.int32)  # the frame runs from c to that side
        r = (d * (position_of(held, v) - i)) % n  # v's offset from c in the frame (0: none)
        one = jnp.ones_like(r)
        if kind == "2opt":  # the stretch succ c .. v reversed: edges (c, v), (succ c, succ v)
            return reverse(held, i, d, one, r), v, c
        # or3opt: the segment C = v and the cities after it, at most `segment` long, moves
        # between c and succ c: three reversals, edges (c, v), (end of C, succ c), (pred v,
        # the city after C)
        length = jax.random.randint(k_len, (m,), 1, segment + 1, jnp.int32)
        # C ends before c's other neighbour: the edge the ant arrived by stays (a v drawn
        # there, without skip_neighbours, makes the three reversals a no-op)
        e = jnp.where(r > 0, jnp.minimum(r + length - 1, n - 2), 0)
        held = reverse(held, i, d, one, e)
        held = reverse(held, i, d, one, e - r + 1)
        held = reverse(held, i, d, e - r + 2, e)
        return held, v, c

    carry = (held, jnp.zeros((m,), jnp.int32), jnp.full((m,), -1, jnp.int32))
    held, _, _ = jax.lax.fori_loop(0, n_moves, move, carry)
    return finish(held)
