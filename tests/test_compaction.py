"""``first_true``: ``jnp.nonzero`` at a static size, and the count, without a scatter-add."""

import jax.numpy as jnp
import numpy as np

from eaco_jax.ops.compaction import first_true


def test_first_true_is_nonzero_and_counts_the_whole_mask():
    rng = np.random.default_rng(0)
    for n in (1, 7, 37, 300, 5000):
        for p in (0.0, 0.1, 0.5, 1.0):
            mask = jnp.asarray(rng.random(n) < p)
            for size in (1, 5, n, n + 13):
                idx, count = first_true(mask, size, 99)
                np.testing.assert_array_equal(
                    idx, jnp.nonzero(mask, size=size, fill_value=99)[0])
                assert int(count) == int(mask.sum())


def test_prefix_sum_by_blocks_is_the_exact_cumsum():
    """The matrix-product prefix sum (forced on here; the GPU's default) equals cumsum for
    integers up to EXACT_INPUT at lengths around the block size, and falls back to cumsum
    where the blocks could not be exact."""
    from eaco_jax.ops.compaction import BLOCK, EXACT_INPUT, prefix_sum

    rng = np.random.default_rng(1)
    for n in (1, 2, BLOCK - 1, BLOCK, BLOCK + 1, 3 * BLOCK + 17, 5000):
        for bound in (1, 64, EXACT_INPUT):
            x = jnp.asarray(rng.integers(-bound, bound + 1, n), jnp.int32)
            got = prefix_sum(x, bound, matmul=True)
            assert got.dtype == jnp.int32
            np.testing.assert_array_equal(got, np.cumsum(np.asarray(x)))
    big = jnp.asarray(rng.integers(0, 10_000, 300), jnp.int32)  # beyond bfloat16: cumsum
    np.testing.assert_array_equal(prefix_sum(big, 10_000, matmul=True), np.cumsum(big))
