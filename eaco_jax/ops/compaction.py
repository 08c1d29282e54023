"""Prefix sums and the indices of a mask's True entries, fast on a GPU and exact.

``jnp.nonzero(mask, size=s)`` counts the entries below each index with a scatter-add of all
``n`` entries into ``s`` bins; on a GPU most of them land in the same few bins (every index
past the last True entry adds to one), and such atomic adds to one address run one after
another. :func:`first_true` computes the same indices with one prefix sum and a binary
search in it.

A long ``jnp.cumsum`` is a ``reduce_window`` on a GPU that reads each entry many times;
:func:`prefix_sum` takes the sums within blocks of :data:`BLOCK` entries as one matrix
product with a triangle of ones (tensor cores; exact for the small integers it is given)
and adds the blocks' offsets from a short cumsum.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array

#: entries per block of :func:`prefix_sum`'s matrix product
BLOCK = 128
#: :func:`prefix_sum` is exact for integers up to this size (bfloat16 holds them exactly; the
#: product accumulates in float32, exact below 2**24)
EXACT_INPUT = 256


def blocks_of(n: int) -> int:
    """The length :func:`prefix_sum` pads ``n`` entries to (a multiple of :data:`BLOCK`): an
    array made that long from the start (zeros or False at its end) is summed without being
    copied into a padded one first, one pass over it fewer."""
    return -(-int(n) // BLOCK) * BLOCK


def prefix_sum(x: Array, bound: int, matmul: bool | None = None) -> Array:
    """Inclusive int32 prefix sum of the 1-d integer (or bool) ``x``, whose entries the caller
    knows to lie in ``[-bound, bound]`` (a static int).

    ``matmul``: blocks by matrix product (see the module docstring), used only where it is
    exact (``bound <= EXACT_INPUT`` and ``n * bound < 2**24``); None: on accelerators only (on
    a CPU the product costs :data:`BLOCK` operations an entry, cumsum one)."""
    n = x.shape[0]
    if matmul is None:
        matmul = jax.default_backend() != "cpu"
    if not matmul or n <= 1 or bound > EXACT_INPUT or n * bound >= 2**24:
        return jnp.cumsum(x, dtype=jnp.int32)
    block = min(BLOCK, n)
    blocks = -(-n // block)
    xb = jnp.pad(x.astype(jnp.bfloat16), (0, blocks * block - n)).reshape(blocks, block)
    triangle = jnp.triu(jnp.ones((block, block), jnp.bfloat16))  # [i, j] = 1 where i <= j
    within = jnp.dot(xb, triangle, preferred_element_type=jnp.float32)
    total = within[:, -1]
    offset = jnp.cumsum(total) - total
    return (within + offset[:, None]).astype(jnp.int32).reshape(-1)[:n]


def first_true(mask: Array, size: int, fill: int) -> tuple[Array, Array]:
    """(indices, count): the indices of the first ``size`` True entries of the 1-d ``mask`` in
    increasing order, ``fill`` after them (``jnp.nonzero(mask, size=size, fill_value=fill)``),
    and the number of True entries of the whole mask (int32). The j-th index is where the
    prefix sum of the mask first reaches j + 1: a binary search of ``size`` entries (unrolled:
    no loop to wait on) instead of a scatter that visits all n."""
    total = prefix_sum(mask, 1)
    idx = jnp.searchsorted(total, jnp.arange(1, size + 1, dtype=jnp.int32), side="left",
                           method="scan_unrolled").astype(jnp.int32)
    return jnp.where(idx < mask.shape[0], idx, jnp.int32(fill)), total[-1]
