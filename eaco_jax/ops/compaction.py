"""Indices of the True entries of a mask, in order, at a static size, without contention.

``jnp.nonzero(mask, size=s)`` counts the entries below each index with a scatter-add of all
``n`` entries into ``s`` bins; on a GPU most of them land in the same few bins (every index
past the last True entry adds to one), and such atomic adds to one address run one after
another. :func:`first_true` computes the same indices with one prefix sum and one scatter
whose writes all go to different places.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def first_true(mask: Array, size: int, fill: int) -> tuple[Array, Array]:
    """(indices, count): the indices of the first ``size`` True entries of the 1-d ``mask`` in
    increasing order, ``fill`` after them (``jnp.nonzero(mask, size=size, fill_value=fill)``),
    and the number of True entries of the whole mask (int32)."""
    rank = jnp.cumsum(mask, dtype=jnp.int32) - 1
    where = jnp.where(mask & (rank < size), rank, size)
    out = jnp.full((size,), fill, jnp.int32)
    out = out.at[where].set(jnp.arange(mask.shape[0], dtype=jnp.int32), mode="drop")
    return out, rank[-1] + 1
