"""MJX's Warp implementation: buffer sizing, refusal where it cannot run, agreement with JAX.

The CUDA tests skip on a machine without a GPU and warp-lang; they run on the GPU host.
"""

from __future__ import annotations

import numpy as np
import pytest

from eaco_jax.errors import ProblemError
from eaco_jax.gait.mjx_import import warp_usable
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_mjx import contact_capacity
from eaco_jax.gait.rollout_native import native_model
from eaco_jax.problems.gait import make_gait_problem

cuda = pytest.mark.skipif(not warp_usable(), reason="needs a CUDA GPU and warp-lang")


def test_capacity_is_an_upper_bound_and_no_larger():
    """The NAO touches the floor with 8 sole spheres (one contact each): 8 contacts, 4
    pyramidal rows each, plus equality and joint-limit rows; native MuJoCo never exceeds
    them on random gaits (falls included)."""
    import mujoco

    spec = load_robot("nao")
    model = native_model(spec, 0.0, "fast")
    contacts, rows = contact_capacity(model)
    spheres = int(np.sum((model.geom_type == 2) & (
        (model.geom_contype | model.geom_conaffinity) > 0)))
    assert contacts == spheres == 8
    assert rows == 4 * contacts + 1 + int(np.sum(model.jnt_limited))  # 1: the eq row
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    most = [0, 0]
    for _ in range(3):
        mujoco.mj_resetDataKeyframe(model, data, 0) if model.nkey else mujoco.mj_resetData(
            model, data)
        for _t in range(400):  # 1.6 s of random targets: the robot falls
            data.ctrl[:] = rng.uniform(model.actuator_ctrlrange[:, 0],
                                       model.actuator_ctrlrange[:, 1])
            mujoco.mj_step(model, data)
            most = [max(most[0], data.ncon), max(most[1], data.nefc)]
    assert 0 < most[0] <= contacts and 0 < most[1] <= rows


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


def test_buffers_hold_every_vmapped_copy():
    """An outer vmap (seeds of one ``minimize``) is flattened by MuJoCo Warp into one batch
    sharing one contact buffer: it holds copies x worlds x the per-world bound; constraint
    rows stay per world. The gait problem asks for it only on Warp."""
    from eaco_jax.gait.rollout_mjx import warp_buffers

    model = native_model(load_robot("nao"), 0.0, "fast")
    contacts, rows = contact_capacity(model)
    assert warp_buffers(model, 512) == (contacts * 512, rows)
    assert warp_buffers(model, 512, copies=10) == (contacts * 5120, rows)
    p = make_gait_problem("nao", backend="mjx", horizon=0.1, impl="jax")
    assert p.for_rows(10) is p
    w = p.replace(impl="warp")
    assert w.for_rows(10).copies == 10 and w.for_rows(1).copies == 1
    from eaco_jax.problems.gait_library import make_gait_library_problem

    lib = make_gait_library_problem(backend="mjx", horizon=0.1, worlds=1, impl="jax")
    assert lib.for_rows(10) is lib
    lib = lib.replace(gait=lib.gait.replace(impl="warp"))
    assert lib.for_rows(10).gait.copies == 10  # the library's seeds share Warp's buffer too


def test_warp_graph_mode_comes_from_the_environment(monkeypatch):
    """``EACO_WARP_GRAPH_MODE``: unset is MJX's default (None); a mode in any case is taken;
    anything else is one line naming the modes."""
    from eaco_jax.errors import ConfigError
    from eaco_jax.gait.rollout_mjx import warp_graph_mode

    monkeypatch.delenv("EACO_WARP_GRAPH_MODE", raising=False)
    assert warp_graph_mode() is None
    monkeypatch.setenv("EACO_WARP_GRAPH_MODE", " Warp_Staged ")
    assert warp_graph_mode() == "warp_staged"
    monkeypatch.setenv("EACO_WARP_GRAPH_MODE", "staged")
    with pytest.raises(ConfigError, match="warp_staged_ex, jax, none"):
        warp_graph_mode()
