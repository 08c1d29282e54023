"""Merge the improvements of several ants into one tour.

On a large instance each ant of a focused colony (``max_new_edges``) changes a few edges of
the same reference tour and its local search repairs them, so an ant that beats the reference
has usually improved one small region of it. Keeping only the iteration's best ant throws
away the other ants' improvements, found elsewhere in the tour at the same cost. This module
combines them, in the spirit of partition crossover (Whitley et al.), restricted to ants that
changed disjoint sets of cities:

* an ant's *touched* cities are those whose pair of tour neighbours differs from the
  reference's; its *gain* is the reference's length minus its own, summed over the edges at
  its touched cities (the edges it removed and added have both ends there);
* the ants with positive gain, best first, are added greedily to a table of neighbour pairs
  that starts as the reference's: an ant whose touched cities are disjoint from those taken
  so far lends its pairs to its touched cities, and is kept if the table is still one cycle
  through all n cities (two moves that are each valid can cut the tour into subtours when
  combined: :func:`is_single_cycle` checks this in O(n log n) work and O(log n) depth, by
  pointer jumping over the 2n directed edges);
* the merged gain is the sum of the kept ants' gains: their changed edges are disjoint.

:func:`tour_from_pairs` turns the table back into a tour (list ranking by pointer jumping).
Everything is a fixed number of wide array steps, so it runs inside the jitted iteration on a
GPU as on a CPU.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from eaco_jax.ops.local_search import changed_cities

Array = jax.Array


def neighbour_pairs(tour: Array) -> Array:
    """``(n, 2)`` int32: each city's predecessor and successor in ``tour`` ``(n,)``."""
    n = tour.shape[0]
    tour = tour.astype(jnp.int32)
    pos = jnp.zeros(n, jnp.int32).at[tour].set(jnp.arange(n, dtype=jnp.int32))
    return jnp.stack([tour[(pos - 1) % n], tour[(pos + 1) % n]], axis=-1)


def _directed_next(pairs: Array) -> Array:
    """The 2n directed edges ``e = 2 c + j`` (from ``c`` to ``pairs[c, j]``) and, for each,
    the directed edge that follows it (leave its head by the head's other neighbour)."""
    n = pairs.shape[0]
    e = jnp.arange(2 * n, dtype=jnp.int32)
    c, j = e // 2, e % 2
    v = pairs[c, j]
    enter = jnp.where(pairs[v, 0] == c, 0, 1)  # the slot of v that points back at c
    return 2 * v + (1 - enter)


def _rounds(n: int) -> int:
    return max(1, math.ceil(math.log2(2 * n)))


def is_single_cycle(pairs: Array) -> Array:
    """Whether the symmetric neighbour table ``pairs`` ``(n, 2)`` (each city's two neighbours;
    n >= 3) is one cycle through every city: its 2n directed edges then form exactly two
    directed cycles (the tour's two orientations). Each edge learns the smallest edge index
    of its cycle by pointer jumping; a cycle's smallest edge is its own label."""
    n = pairs.shape[0]
    nxt = _directed_next(pairs)
    label = jnp.arange(2 * n, dtype=jnp.int32)

    def jump(_, carry):
        label, nxt = carry
        return jnp.minimum(label, label[nxt]), nxt[nxt]

    label, _ = jax.lax.fori_loop(0, _rounds(n), jump, (label, nxt))
    return jnp.sum(label == jnp.arange(2 * n, dtype=jnp.int32)) == 2


def tour_from_pairs(pairs: Array) -> Array:
    """The tour ``(n,)`` of a neighbour table that :func:`is_single_cycle` accepts, starting
    at city 0 towards ``pairs[0, 1]``: each directed edge of that orientation learns its
    distance to the orientation's last edge by pointer jumping (list ranking)."""
    n = pairs.shape[0]
    nxt = _directed_next(pairs)
    first = jnp.int32(1)  # city 0 -> pairs[0, 1]
    e = jnp.arange(2 * n, dtype=jnp.int32)
    last = nxt == first  # the edge that returns to city 0 along this orientation
    nxt = jnp.where(last, e, nxt)
    steps = jnp.where(last, 0, 1).astype(jnp.int32)

    def jump(_, carry):
        steps, nxt = carry
        return steps + steps[nxt], nxt[nxt]

    steps, nxt = jax.lax.fori_loop(0, _rounds(n), jump, (steps, nxt))
    on = last[nxt]  # edges of the orientation reach the last edge; the other one never does
    where = jnp.where(on, n - 1 - steps, n)
    return jnp.zeros(n, jnp.int32).at[where].set(e // 2, mode="drop")


def merge_improvements(ref: Array, tours: Array, dist: Array, top: int
                       ) -> tuple[Array, Array, Array, Array]:
    """Merge the improving ants of ``tours`` ``(m, n)`` into the reference tour ``ref``
    ``(n,)`` (module docstring): of the ``top`` ants with the largest gains, best first, each
    whose touched cities are disjoint from those already taken and whose addition leaves one
    cycle. ``dist[a, b]``: a distance matrix or the sparse problem's coordinate distances.

    Returns ``(tour, gain, merged, worst)``: the merged tour, its gain over ``ref`` (float32,
    the sum of the kept ants' gains), how many ants it combines (0: no ant improves ``ref``,
    and ``tour`` is ``ref``'s cycle) and the ant with the smallest gain (the one a colony can
    replace by the merge).
    """
    m, n = tours.shape
    top = max(1, min(int(top), m))
    ref_pairs = neighbour_pairs(ref)
    pairs = jax.vmap(neighbour_pairs)(tours)  # (m, n, 2)
    touched = changed_cities(tours, ref)  # a city on a new edge: its pair of neighbours changed
    cities = jnp.arange(n, dtype=jnp.int32)
    ref_d = dist[cities, ref_pairs[:, 0]] + dist[cities, ref_pairs[:, 1]]
    ant_d = dist[cities[None, :], pairs[..., 0]] + dist[cities[None, :], pairs[..., 1]]
    gain = 0.5 * jnp.sum(jnp.where(touched, ref_d[None, :] - ant_d, 0.0), axis=1)
    order = jnp.argsort(-gain)[:top]

    def add(i, carry):
        table, used, total, count = carry
        a = order[i]
        mine = touched[a]
        fits = (gain[a] > 0) & ~jnp.any(mine & used)
        trial = jnp.where(mine[:, None], pairs[a], table)
        # the first ant taken is a tour of its own; a later one needs the check, which only
        # runs for an ant that fits (most do not improve; under vmap both branches run)
        keep = jax.lax.cond(fits & (count > 0), is_single_cycle, lambda _: fits, trial)
        return (jnp.where(keep, trial, table), used | (keep & mine),
                total + jnp.where(keep, gain[a], 0.0), count + keep.astype(jnp.int32))

    table, _, total, count = jax.lax.fori_loop(
        0, top, add, (ref_pairs, jnp.zeros(n, bool), jnp.float32(0.0), jnp.int32(0)))
    return tour_from_pairs(table), total.astype(jnp.float32), count, jnp.argmin(gain)


__all__ = ["is_single_cycle", "merge_improvements", "neighbour_pairs", "tour_from_pairs"]
