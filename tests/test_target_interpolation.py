"""Targets interpolated between control steps (nao.json ``motors.interpolate_targets``).

NAO's DCM moves a joint's position command linearly from one timed command to the next at
every DCM cycle; held for a whole 20 ms control step instead, a moving target jumps once per
control step and the stiff position loop answers each jump with a torque pulse that heats the
motor (``experiments/nao_standing_heat.py``).
"""

import json

import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.gait import motors as mo
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_native import native_rollout, physics_controls
from eaco_jax.gait.worlds import couple_controls
from eaco_jax.problems.gait import make_gait_problem


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_physics_targets_hand_case(xp):
    u = xp.asarray([[0.0, 1.0]], xp.float32)
    nxt = xp.asarray([[1.0, 1.0]], xp.float32)
    lin = np.asarray(mo.physics_targets(u, nxt, 5, True, xp))
    np.testing.assert_allclose(lin[0, :, 0], [0.0, 0.2, 0.4, 0.6, 0.8], atol=1e-7)
    np.testing.assert_allclose(lin[0, :, 1], 1.0)  # a target that does not move stays
    held = np.asarray(mo.physics_targets(u, nxt, 5, False, xp))
    np.testing.assert_allclose(held[0, :, 0], 0.0)
    assert held.shape == lin.shape == (1, 5, 2)


def test_physics_controls_chunks_and_the_last_step():
    """Chunks of the horizon join up (a chunk's last physics steps move toward the first
    target of the next chunk) and the last control step is held."""
    c = np.arange(4, dtype=np.float64)[None, :, None]  # targets 0, 1, 2, 3
    whole = physics_controls(c, 0, 4, 2, True)[0, :, 0]
    np.testing.assert_allclose(whole, [0, 0.5, 1, 1.5, 2, 2.5, 3, 3])
    parts = np.concatenate([physics_controls(c, 0, 2, 2, True), physics_controls(c, 2, 4, 2, True)],
                           axis=1)[0, :, 0]
    np.testing.assert_allclose(parts, whole)
    np.testing.assert_allclose(physics_controls(c, 0, 4, 2, False)[0, :, 0],
                               [0, 0, 1, 1, 2, 2, 3, 3])


def test_only_the_nao_spec_interpolates(nao):
    assert mo.interpolates_targets(nao)
    assert not mo.interpolates_targets(load_robot("op3"))


def test_interpolated_targets_cut_the_copper_loss(nao):
    """The stored gait, 2 s on native MuJoCo with the limits in the physics: interpolated
    targets walk about as far with far less copper loss than held ones."""
    best = json.loads(open("experiments/results/nao_best_gait.json").read())
    p = make_gait_problem(nao, backend="native", horizon=2.0)
    ctrl = couple_controls(np.asarray(p.controls(jnp.asarray([best["vector"]], jnp.float32))),
                           nao, xp=np)
    out = {i: native_rollout(ctrl, nao, quality=True, interpolate=i) for i in (True, False)}
    loss = {i: float(out[i]["acc"]["loss_j"].sum()) for i in out}
    x = {i: float(out[i]["trace"][0, -1, 0]) for i in out}
    assert loss[True] < 0.75 * loss[False]
    assert x[True] == pytest.approx(x[False], abs=0.1)
    default = native_rollout(ctrl, nao, quality=True)  # the spec's: interpolated
    np.testing.assert_array_equal(default["acc"]["loss_j"], out[True]["acc"]["loss_j"])
