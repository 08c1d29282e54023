"""Integer encodings shared by every tour-construction plan and the construction kernel.

* Packed keys: a non-negative float32 score's bits (monotonic for such floats) in the high
  bits of an int32 and a column index in the low bits, so one integer max is an argmax with
  ties broken by column. Every greedy and whole-row fallback choice compares these keys,
  which is why all plans pick the same nodes.
* Tabu bit masks: ``ceil(n / 32)`` uint32 words per ant, bit ``j`` of word ``w`` set while
  node ``32 w + j`` is still to visit.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def id_bits(width: int) -> int:
    """Low bits a packed key keeps for a column index below ``width``."""
    return max(1, (width - 1).bit_length())


def packed_keys(score: Array, col: Array, bits_for_id: int) -> Array:
    """int32 keys of non-negative float ``score`` with column ``col`` in the low
    ``bits_for_id`` bits (scores within 2^-(23 - bits_for_id) relative count as ties)."""
    bits = jax.lax.bitcast_convert_type(score, jnp.int32)
    return (bits & ~((1 << bits_for_id) - 1)) | col


def bit_allowed(flat_bits, word_base: Array, node: Array) -> Array:
    """Whether ``node`` is still to visit: bit ``node % 32`` of word ``word_base + node // 32``
    of a flat tabu bit mask (an array, or the construction kernel's Pallas ref)."""
    word = flat_bits[word_base + (node >> 5)]
    return ((word >> (node & 31).astype(jnp.uint32)) & 1) == 1
