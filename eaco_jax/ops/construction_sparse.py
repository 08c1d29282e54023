"""Tour construction on candidate lists alone: one ant's step costs O(k), never O(n).

The rule on the candidates is that of :func:`eaco_jax.ops.construction.construct_tours` (Eq. 2
and the q0 rule over the candidates that are not tabu, the same uniforms, the same
:func:`~eaco_jax.ops.construction._sample`), so with lists of every other city (k = n - 1)
both build the same tours. They differ only where every candidate is tabu: there the dense
plans search the ant's whole row for the allowed node of largest weight (O(n)); here the ant
takes the next city not yet visited in the order of a reference tour (Focused ACO's rule;
the colony passes its best tour so far), in O(1): each ant keeps its unvisited cities as a
doubly linked list in the reference tour's order, and a visited city's ``next`` entry still
names the first unvisited city after it until the ant's next move.

Focused construction (Focused ACO's idea, ``max_new_edges``): once an ant has added that many
edges that are not edges of the reference tour, it stops choosing and follows the reference
tour's order for the rest (the fallback rule for every remaining step), so each tour differs
from the reference in a bounded number of places and the local search has little to repair.

Memory per construction: the tabu mask (1 byte), the two list arrays (8 bytes) and the path
(4 bytes) per ant and city, and the (R, k) choice information.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from eaco_jax.ops.construction import UNROLL, _pack_bits, _sample, kernel_compiles_here

Array = jax.Array


def linked_order(ref_tour: Array) -> tuple[Array, Array]:
    """``(succ, pred)`` of every city in the closed reference tour: int32 (n,) each."""
    ref = jnp.asarray(ref_tour, jnp.int32)
    succ = jnp.zeros_like(ref).at[ref].set(jnp.roll(ref, -1))
    pred = jnp.zeros_like(ref).at[ref].set(jnp.roll(ref, 1))
    return succ, pred


def _unlink(nxt_l: Array, prv_l: Array, ants: Array, city: Array) -> tuple[Array, Array]:
    """Remove ``city[a]`` from ant a's list (its own entries stay, naming its neighbours)."""
    p = prv_l[ants, city]
    s = nxt_l[ants, city]
    nxt_l = nxt_l.at[ants, p].set(s, unique_indices=True)
    prv_l = prv_l.at[ants, s].set(p, unique_indices=True)
    return nxt_l, prv_l


def candidate_rows(cand_w: Array, candidates: Array, m: int, q0: Array | float,
                   row_offset: Array | None) -> tuple[Array, Array, Array]:
    """The per-ant arguments both candidate-list constructions take, checked and shaped:
    ``(candidates int32 (n, k), q0 float32 (m,), row_offset int32 (m,), default 0)``;
    ``cand_w`` must be ``(multiple of n, k)``."""
    n, k = candidates.shape
    if cand_w.shape[0] % n or cand_w.shape[1] != k:
        raise ValueError(f"cand_w must be (multiple of {n}, {k}), got {cand_w.shape}")
    row_offset = (jnp.zeros((m,), jnp.int32) if row_offset is None
                  else jnp.asarray(row_offset, jnp.int32))
    q0 = jnp.broadcast_to(jnp.asarray(q0, jnp.float32), (m,))
    return jnp.asarray(candidates, jnp.int32), q0, row_offset


def construct_tours_sparse(
    key: Array,
    cand_w: Array,
    candidates: Array,
    starts: Array,
    ref_tour: Array,
    q0: Array | float = 0.0,
    row_offset: Array | None = None,
    factor: Array | None = None,
    max_new_edges: int | None = None,
    plan: str = "scan",
) -> Array:
    """Build one tour per ant on candidate lists.

    Args:
      key: PRNG key (the draws of ``construct_tours``: one row of uniforms per step).
      cand_w: (R, k) non-negative choice weights of the candidates (R = n, or stacked
        multiples of n: an ant at node i reads row ``row_offset[a] + i``).
      candidates: (n, k) int32 candidate lists.
      starts: (m,) start nodes.
      ref_tour: (n,) the reference tour whose order the fallback follows.
      q0: probability of the greedy choice, scalar or (m,).
      row_offset: (m,) multiples of n (default 0).
      factor: optional (m, n) multiplicative perturbation of the weights (chaos).
      max_new_edges: focused construction (module docstring); None: choose at every step.
      plan: "scan" (a batched step per tour position, any backend) or "kernel" (one Pallas
        kernel per block of ants, ``construction_kernel.construct_tours_sparse_kernel``;
        compiled on a GPU, else in Pallas' interpreter); both build the same tours, up to
        the kernel's order of adding prefix sums (see ``construction_kernel``).

    Returns:
      (m, n) int32 tours starting at ``starts``.
    """
    n, k = candidates.shape
    m = starts.shape[0]
    cands, q0, row_offset = candidate_rows(cand_w, candidates, m, q0, row_offset)
    starts = starts.astype(jnp.int32)
    every = jnp.arange(m, dtype=jnp.int32)
    ant_base = (every * n)[:, None]
    alive = jnp.arange(n)[None, :] != starts[:, None]
    succ, pred = linked_order(ref_tour)
    nxt_l = jnp.broadcast_to(succ, (m, n))
    prv_l = jnp.broadcast_to(pred, (m, n))
    nxt_l, prv_l = _unlink(nxt_l, prv_l, every, starts)
    uniforms = jax.random.uniform(key, (max(n - 1, 1), m))[: n - 1]
    if plan == "kernel":
        from eaco_jax.ops import construction_kernel

        return construction_kernel.construct_tours_sparse_kernel(
            uniforms, cand_w, cands, starts, q0, row_offset, factor, _pack_bits(alive),
            nxt_l, prv_l, succ, pred, cap=max_new_edges, interpret=not kernel_compiles_here(),
            block=construction_kernel.BLOCK)
    if plan != "scan":
        raise ValueError(f"plan={plan!r} is not one of scan, kernel")

    def step(carry, u):
        current, alive, nxt_l, prv_l, new = carry
        row = row_offset + current
        cand = cands[current]
        w = jnp.where(alive.reshape(-1)[ant_base + cand], cand_w[row], 0.0)  # (m, k)
        w = w if factor is None else w * factor.reshape(-1)[ant_base + cand]
        c, ok = _sample(w, u, q0)
        nxt = jnp.take_along_axis(cand, c[:, None], axis=1)[:, 0]
        if max_new_edges is not None:  # done changing the reference: follow it
            ok = ok & (new < max_new_edges)
        nxt = jnp.where(ok, nxt, nxt_l[every, current])  # every candidate tabu: follow ref
        if max_new_edges is not None:
            new = new + ((nxt != succ[current]) & (nxt != pred[current])).astype(jnp.int32)
        nxt_l, prv_l = _unlink(nxt_l, prv_l, every, nxt)
        alive = alive.at[every, nxt].set(False, unique_indices=True)
        return (nxt, alive, nxt_l, prv_l, new), nxt

    carry = (starts, alive, nxt_l, prv_l, jnp.zeros((m,), jnp.int32))
    _, path = jax.lax.scan(step, carry, uniforms, unroll=UNROLL)
    return jnp.concatenate([starts[:, None], path.T], axis=1)


def hilbert_tour(coords: Array, order: int = 15) -> Array:
    """(n,) int32 cities in the order of a Hilbert curve over their bounding box (a tour
    within a small factor of the optimum, in O(n log n)): the first tour of the sparse path."""
    xy = jnp.asarray(coords, jnp.float32)
    lo = jnp.min(xy, axis=0)
    span = jnp.maximum(jnp.max(jnp.max(xy, axis=0) - lo), 1e-30)
    side = (1 << order) - 1
    g = jnp.clip(jnp.floor((xy - lo) / span * side), 0, side).astype(jnp.int32)
    x, y = g[:, 0], g[:, 1]
    d = jnp.zeros_like(x)
    s = 1 << (order - 1)
    while s > 0:  # the classic xy -> d conversion, one bit level at a time
        rx = ((x & s) > 0).astype(jnp.int32)
        ry = ((y & s) > 0).astype(jnp.int32)
        d = d + s * s * ((3 * rx) ^ ry)
        flip = ry == 0
        swap_x = jnp.where(flip & (rx == 1), s - 1 - x, x)
        swap_y = jnp.where(flip & (rx == 1), s - 1 - y, y)
        x, y = jnp.where(flip, swap_y, swap_x), jnp.where(flip, swap_x, swap_y)
        s >>= 1
    return jnp.argsort(d, stable=True).astype(jnp.int32)
