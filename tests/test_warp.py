"""MJX's Warp implementation: buffer sizing, refusal where it cannot run, agreement with JAX.

The CUDA tests skip on a machine without a GPU and warp-lang; they run on the GPU host.
"""

from __future__ import annotations

import numpy as np
import pytest
from eaco_jax.robots import load_robot

from eaco_jax.errors import ProblemError
from eaco_jax.gait.mjx_import import warp_usable
from eaco_jax.gait.rollout_mjx import contact_capacity
from eaco_jax.gait.rollout_native import native_model
from eaco_jax.problems.gait import make_gait_problem

cuda = pytest.mark.skipif(not warp_usable(), reason="needs a CUDA GPU and warp-lang")


def test_capacity_counts_the_model_contacts():
    model = native_model(load_robot("nao"), 0.0, "fast")
    contacts, rows = contact_capacity(model)
    floor_touching = int(np.sum((model.geom_type != 0) & (
        (model.geom_contype | model.geom_conaffinity) > 0)))
    assert contacts >= 4 * floor_touching > 0
    assert rows >= contacts * 2 * (int(model.geom_condim.max()) - 1)


def test_auto_picks_jax_off_gpu_and_warp_is_refused_with_the_fix():
    if warp_usable():
        pytest.skip("this machine can run warp")
    assert make_gait_problem("nao", backend="mjx", horizon=0.1).impl == "jax"
    with pytest.raises(ProblemError, match="eaco-jax\\[gpu\\]"):
        make_gait_problem("nao", backend="mjx", horizon=0.1, impl="warp")


@cuda
def test_warp_agrees_with_jax_on_a_short_walk():
    import jax.numpy as jnp

    x = None
    res = {}
    for impl in ("warp", "jax"):
        p = make_gait_problem("nao", backend="mjx", horizon=1.0, impl=impl)
        if x is None:
            lo, hi = np.asarray(p.lower), np.asarray(p.upper)
            x = jnp.asarray(lo + (hi - lo) * np.random.default_rng(0).random((16, lo.size)),
                            jnp.float32)
        res[impl] = np.asarray(p.trace(x))
    np.testing.assert_allclose(res["warp"][:, -1, :3], res["jax"][:, -1, :3], atol=2e-2)


@cuda
def test_overflow_is_reported(capfd, monkeypatch):
    import jax
    import jax.numpy as jnp

    from eaco_jax.gait import rollout_mjx

    monkeypatch.setattr(rollout_mjx, "CAPACITY_MARGIN", 0.05)
    p = make_gait_problem("nao", backend="mjx", horizon=0.2, impl="warp")
    x = jnp.broadcast_to((p.lower + p.upper) / 2, (8, p.dim))
    jax.block_until_ready(rollout_mjx.mjx_rollout(p.controls(x), p.spec, impl="warp")["trace"])
    assert "MuJoCo Warp buffers overflowed" in capfd.readouterr().err
