"""Genetic operators on tours: crossover (ERX, PMX) and mutation (inversion, swap).

These are the "mutated" part of EACO (paper Fig. 1: ERX vs PMX). Every function works on ONE
tour (``(n,)`` int32 permutation of ``0..n-1``) with its own PRNG key, uses ``fori_loop`` /
``while_loop`` / index arithmetic inside, and is meant to be ``jax.vmap``-ed over a colony.

* :func:`erx` - edge recombination (Whitley, Starkweather & Fuquay 1989): the edge map is the
  union of both parents' neighbours; from the current city go to the unvisited neighbour with the
  fewest remaining (unvisited) neighbours, ties broken at random, and to a random unvisited city
  when no neighbour is left. Children inherit almost all of their edges from the parents.
* :func:`pmx` - partially mapped crossover (Goldberg & Lingle 1985): the child copies
  ``parent_a`` between two random cut points and ``parent_b`` elsewhere, resolving repeats by
  the segment's mapping ``a[i] <-> b[i]``. It preserves positions rather than edges.
* :func:`inversion_mutation` reverses a random segment (a random 2-opt move);
  :func:`swap_mutation` exchanges two random cities.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def _inverse(perm: Array) -> Array:
    """Position of every city: ``inv[perm[i]] = i``."""
    n = perm.shape[0]
    return jnp.zeros(n, jnp.int32).at[perm].set(jnp.arange(n, dtype=jnp.int32))


def edge_map(parent_a: Array, parent_b: Array) -> tuple[Array, Array]:
    """Union of both parents' neighbours: ``(n, 4)`` cities and a mask of distinct entries."""
    n = parent_a.shape[0]
    pa, pb = _inverse(parent_a), _inverse(parent_b)
    adj = jnp.stack(
        [
            parent_a[(pa - 1) % n],
            parent_a[(pa + 1) % n],
            parent_b[(pb - 1) % n],
            parent_b[(pb + 1) % n],
        ],
        axis=1,
    )
    # keep the first occurrence of each neighbour (a shared edge appears twice)
    earlier = jnp.tril(jnp.ones((4, 4), bool), -1)  # earlier[j, i]: i < j
    dup = jnp.any((adj[:, :, None] == adj[:, None, :]) & earlier[None], axis=2)
    return adj, ~dup


def erx(key: Array, parent_a: Array, parent_b: Array) -> Array:
    """Edge recombination crossover of two tours; the child starts at ``parent_a[0]``."""
    parent_a = jnp.asarray(parent_a, jnp.int32)
    parent_b = jnp.asarray(parent_b, jnp.int32)
    n = parent_a.shape[0]
    adj, valid = edge_map(parent_a, parent_b)
    k_tie, k_stuck = jax.random.split(key)
    tie = jax.random.uniform(k_tie, (n, 4), maxval=0.5)  # < 1: only breaks ties of counts
    stuck_order = jax.random.permutation(k_stuck, n)  # random priority for dead ends
    start = parent_a[0]

    def step(i, carry):
        tour, visited = carry
        cur = tour[i - 1]
        nb = adj[cur]
        ok = valid[cur] & ~visited[nb]
        remaining = jnp.sum(valid[nb] & ~visited[adj[nb]], axis=1)
        score = jnp.where(ok, remaining + tie[i], jnp.inf)
        choice = nb[jnp.argmin(score)]
        fallback = jnp.argmin(jnp.where(visited, n, stuck_order)).astype(jnp.int32)
        nxt = jnp.where(jnp.any(ok), choice, fallback)
        return tour.at[i].set(nxt), visited.at[nxt].set(True)

    tour = jnp.zeros(n, jnp.int32).at[0].set(start)
    visited = jnp.zeros(n, bool).at[start].set(True)
    tour, _ = jax.lax.fori_loop(1, n, step, (tour, visited))
    return tour


def pmx_at(parent_a: Array, parent_b: Array, lo: Array, hi: Array) -> Array:
    """PMX with the segment ``[lo, hi]`` (inclusive positions) taken from ``parent_a``."""
    parent_a = jnp.asarray(parent_a, jnp.int32)
    parent_b = jnp.asarray(parent_b, jnp.int32)
    n = parent_a.shape[0]
    idx = jnp.arange(n)
    in_segment = (idx >= lo) & (idx <= hi)
    pos_a = _inverse(parent_a)
    taken = in_segment[pos_a]  # city already placed by parent_a's segment

    def resolve(v, inside):
        # outside the segment follow the mapping a[i] -> b[i] until the city is not in a's
        # segment (chains end there; inside the segment they could cycle, so skip those)
        return jax.lax.while_loop(lambda v: taken[v] & ~inside, lambda v: parent_b[pos_a[v]], v)

    outside = jax.vmap(resolve)(parent_b, in_segment)
    return jnp.where(in_segment, parent_a, outside)


def pmx(key: Array, parent_a: Array, parent_b: Array) -> Array:
    """Partially mapped crossover with two random cut points."""
    n = parent_a.shape[0]
    cuts = jax.random.randint(key, (2,), 0, n)
    return pmx_at(parent_a, parent_b, cuts.min(), cuts.max())


def inversion_mutation(key: Array, tour: Array) -> Array:
    """Reverse a random segment of 2..n-2 cities (so the cycle changes; needs n >= 4)."""
    tour = jnp.asarray(tour, jnp.int32)
    n = tour.shape[0]
    k_len, k_start = jax.random.split(key)
    length = jax.random.randint(k_len, (), 2, max(n - 1, 3))
    lo = jax.random.randint(k_start, (), 0, n - length + 1)
    hi = lo + length - 1
    idx = jnp.arange(n)
    return tour[jnp.where((idx >= lo) & (idx <= hi), lo + hi - idx, idx)]


def swap_mutation(key: Array, tour: Array) -> Array:
    """Exchange the cities at two distinct random positions."""
    tour = jnp.asarray(tour, jnp.int32)
    n = tour.shape[0]
    k_i, k_j = jax.random.split(key)
    i = jax.random.randint(k_i, (), 0, n)
    j = (i + jax.random.randint(k_j, (), 1, n)) % n
    return tour.at[i].set(tour[j]).at[j].set(tour[i])
