"""Population diversity of a colony of tours (the paper's "genotype method").

The distance between two tours is the fraction of edges they do not share (undirected, so a
tour and its reverse are identical); the colony's diversity is the mean distance over all pairs
of ants, in ``[0, 1]``: 0 when every ant walks the same cycle, near 1 for unrelated tours.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


@jax.jit
def edge_diversity(tours: Array) -> Array:
    """Mean pairwise edge distance ``1 - shared / n`` of tours ``(m, n)``: float32 in [0, 1].

    O(m n) time, O(n^2) memory: summed over ordered pairs of ants, the shared edges are
    sum_e c_e (c_e - 1), where c_e is the number of tours using undirected edge e (so no
    (m, m) table is built). 0 for a colony of one ant.
    """
    tours = jnp.asarray(tours, jnp.int32)
    if tours.ndim != 2:
        raise ValueError(f"tours must have shape (m, n), got {tours.shape}")
    m, n = tours.shape
    if m < 2 or n < 3:
        return jnp.zeros((), jnp.float32)
    nxt = jnp.roll(tours, -1, axis=1)
    edge = jnp.minimum(tours, nxt) * n + jnp.maximum(tours, nxt)  # undirected edge id
    count = jnp.zeros((n * n,), jnp.float32).at[edge.reshape(-1)].add(1.0)
    shared = jnp.sum(count * (count - 1.0))  # ordered pairs (a, b), a != b
    pairs = jnp.float32(n * m * (m - 1))  # exact while below 2^24, like ``shared``
    return jnp.clip((pairs - shared) / pairs, 0.0, 1.0).astype(jnp.float32)
