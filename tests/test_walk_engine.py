"""Walk engine: bounds, standing pose at t=0, joint limits, vmappability, ant oscillator."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.robot import load_robot


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def test_layout_and_bounds():
    assert len(we.PARAM_NAMES) == 14 == len(we.LOWER) == len(we.UPPER)
    assert np.all(we.LOWER < we.UPPER)
    assert len(we.ANT_PARAM_NAMES) == len(we.ANT_LOWER) == len(we.ANT_UPPER)


def test_starts_from_standing_keyframe(nao):
    p = jnp.asarray((we.LOWER + we.UPPER) / 2)
    q0 = we.joint_targets(p, jnp.float32(0.0), nao)
    np.testing.assert_allclose(q0, np.asarray(nao.stand_ctrl), atol=2e-3)


def test_targets_within_limits_and_vmappable(nao):
    key = jax.random.PRNGKey(0)
    p = we.LOWER + (we.UPPER - we.LOWER) * jax.random.uniform(key, (32, 14))
    t = jnp.linspace(0.0, 3.0, 50)
    q = jax.jit(jax.vmap(jax.vmap(lambda pp, tt: we.joint_targets(pp, tt, nao),
                                  (None, 0)), (0, None)))(p, t)
    assert q.shape == (32, 50, 22)
    assert np.all(np.isfinite(q))
    assert np.all(q >= np.asarray(nao.joint_lower) - 1e-6)
    assert np.all(q <= np.asarray(nao.joint_upper) + 1e-6)


def test_gait_is_periodic_after_ramp(nao):
    names = dict(zip(we.PARAM_NAMES, (we.LOWER + we.UPPER) / 2, strict=True))
    names.update(step_length=0.08, period=0.5, turn_rate=0.0)
    p = jnp.asarray([names[n] for n in we.PARAM_NAMES], jnp.float32)
    a = we.joint_targets(p, jnp.float32(2.1), nao)
    b = we.joint_targets(p, jnp.float32(2.6), nao)
    np.testing.assert_allclose(a, b, atol=1e-4)
    # legs alternate: half a period later the left leg does what the right leg did
    c = we.joint_targets(p, jnp.float32(2.35), nao)
    li, ri = nao.joint_names.index("LKneePitch"), nao.joint_names.index("RKneePitch")
    np.testing.assert_allclose(a[li], c[ri], atol=1e-4)
    assert float(we.gait_speed(p)) == pytest.approx(0.08 / (names["duty_ratio"] * 0.5))


def test_swing_foot_lifts(nao):
    """During swing the knee bends more than in stance (the foot is lifted)."""
    p = dict(zip(we.PARAM_NAMES, we.LOWER, strict=True))
    p.update(hip_height=0.21, duty_ratio=0.6, period=0.5, foot_lift=0.03)
    v = jnp.asarray([p[n] for n in we.PARAM_NAMES], jnp.float32)
    knee = nao.joint_names.index("LKneePitch")
    stance = we.joint_targets(v, jnp.float32(2.0 + 0.15), nao)[knee]  # phase 0.3 < d
    swing = we.joint_targets(v, jnp.float32(2.0 + 0.4), nao)[knee]  # phase 0.8 mid-swing
    assert float(swing) > float(stance) + 0.1


def test_ant_oscillator():
    ant = load_robot("ant")
    p = jnp.asarray((we.ANT_LOWER + we.ANT_UPPER) / 2)
    q = jax.vmap(lambda t: we.joint_targets(p, t, ant))(jnp.linspace(0, 2, 20))
    assert q.shape == (20, 8)
    np.testing.assert_allclose(q[0], np.asarray(ant.stand_ctrl), atol=1e-6)
    assert np.all(q >= np.asarray(ant.joint_lower) - 1e-6)


def test_slope_keeps_soles_parallel_to_the_floor(nao):
    p = jnp.asarray((we.LOWER + we.UPPER) / 2)
    flat = we.joint_targets(p, jnp.float32(2.0), nao, 0.0, 0.0)
    up = we.joint_targets(p, jnp.float32(2.0), nao, 0.0, 5.0)
    i = nao.joint_names.index("LAnklePitch")
    pose = we.stand_pose(nao, 5.0)
    assert pose[i] == pytest.approx(nao.stand_ctrl[i] - np.radians(5.0))
    assert not np.allclose(flat, up)
    np.testing.assert_allclose(we.stand_pose(nao, 0.0), nao.stand_ctrl)
