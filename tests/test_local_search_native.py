"""The numba don't-look-bit search returns the XLA search's tours, also where ``vmap`` and
``jit`` wrap it (islands, the colony step) and on a TSPLIB instance with real-valued gains."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.ops.local_search import dlb_local_search, resolve_dlb_impl
from eaco_jax.problems import TSP, load_tsplib


def _tours(n, m, seed):
    rng = np.random.default_rng(seed)
    return np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32)


@pytest.mark.parametrize("or_opt,full_check", [(False, False), (True, False), (True, True)])
def test_native_returns_the_xla_tours_on_pcb442(or_opt, full_check):
    p = load_tsplib("pcb442")
    tours = _tours(p.n, 4, 5)
    key = jax.random.key(3)
    got = [dlb_local_search(key, tours, p.dist, p.neighbors, or_opt=or_opt,
                            full_check=full_check, return_moves=True, impl=impl)
           for impl in ("xla", "native")]
    np.testing.assert_array_equal(np.asarray(got[0][0]), np.asarray(got[1][0]))
    np.testing.assert_array_equal(np.asarray(got[0][1]), np.asarray(got[1][1]))
    assert int(np.asarray(got[1][1]).min()) > 0  # the search did work on random tours


def test_native_matches_xla_on_float_distances_under_vmap():
    # random points: real-valued distances, where the order of the float32 sums matters
    rng = np.random.default_rng(7)
    p = TSP.from_coords(rng.uniform(0, 1, (60, 2)), neighbors=8)
    tours = jnp.asarray(np.stack([_tours(60, 3, s) for s in range(2)]))  # (2 islands, 3, 60)
    keys = jax.random.split(jax.random.key(0), 2)

    def run(impl):
        f = jax.jit(jax.vmap(lambda k, t: dlb_local_search(k, t, p.dist, p.neighbors,
                                                           or_opt=True, impl=impl)))
        return np.asarray(f(keys, tours))

    xla, native = run("xla"), run("native")
    np.testing.assert_array_equal(xla, native)
    assert not np.array_equal(native, np.asarray(tours))


def test_impl_choice_and_bad_name():
    assert resolve_dlb_impl("auto") == ("native" if jax.default_backend() == "cpu" else "xla")
    assert resolve_dlb_impl("xla") == "xla"
    with pytest.raises(ValueError, match="impl='numba' is not one of"):
        resolve_dlb_impl("numba")
