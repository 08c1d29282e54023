"""``first_true``: ``jnp.nonzero`` at a static size, and the count, without a scatter-add."""

import jax.numpy as jnp
import numpy as np

from eaco_jax.ops.compaction import first_true


def test_first_true_is_nonzero_and_counts_the_whole_mask():
    rng = np.random.default_rng(0)
    for n in (1, 7, 37):
        for p in (0.0, 0.1, 0.5, 1.0):
            mask = jnp.asarray(rng.random(n) < p)
            for size in (1, 5, n, n + 13):
                idx, count = first_true(mask, size, 99)
                np.testing.assert_array_equal(
                    idx, jnp.nonzero(mask, size=size, fill_value=99)[0])
                assert int(count) == int(mask.sum())
