"""Leg IK: forward-kinematics round trip (analytic FK and MuJoCo's NAO model)."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from eaco_jax.gait.ik import leg_fk, leg_ik
from eaco_jax.gait.robot import load_model, load_robot

THIGH, TIBIA = 0.1, 0.1029


def _targets(n=64, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.06, 0.06, n)
    y = rng.uniform(-0.04, 0.04, n)
    z = -rng.uniform(0.12, 0.18, n)  # all within reach (< 0.2029 m)
    yaw = rng.uniform(-0.3, 0.3, n)
    return jnp.asarray(np.stack([x, y, z], -1), jnp.float32), jnp.asarray(yaw, jnp.float32)


def test_round_trip_analytic_fk():
    ankle, yaw = _targets()
    q = jax.jit(lambda a, y: leg_ik(a, y, THIGH, TIBIA))(ankle, yaw)
    pos, rot = leg_fk(q, THIGH, TIBIA)
    np.testing.assert_allclose(pos, ankle, atol=1e-5)
    # the sole stays parallel to the torso: foot z axis is vertical, its x axis has the yaw
    np.testing.assert_allclose(rot[:, :, 2], np.tile([0.0, 0.0, 1.0], (len(yaw), 1)), atol=1e-5)
    np.testing.assert_allclose(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]), yaw, atol=1e-5)


def test_unreachable_target_is_clipped_not_nan():
    q = leg_ik(jnp.array([0.0, 0.0, -0.5]), jnp.array(0.0), THIGH, TIBIA)
    assert np.all(np.isfinite(q))
    assert abs(float(q[3])) < 0.1  # nearly straight knee


def test_round_trip_mujoco_model():
    spec = load_robot("nao")
    model = load_model(spec)
    data = mujoco.MjData(model)
    ankle, yaw = _targets(8, seed=1)
    q = np.asarray(leg_ik(ankle, yaw, spec.geom("thigh"), spec.geom("tibia")))
    joints = ["LHipYawPitch", "LHipRoll", "LHipPitch", "LKneePitch", "LAnklePitch", "LAnkleRoll"]
    for i in range(len(yaw)):
        data.qpos[:] = 0.0
        data.qpos[3] = 1.0
        for j, name in enumerate(joints):
            data.qpos[model.joint(name).qposadr[0]] = q[i, j]
        mujoco.mj_kinematics(model, data)
        hip = data.xpos[model.body("l_pelvis").id]
        rel = data.xpos[model.body("l_ankle").id] - hip
        np.testing.assert_allclose(rel, np.asarray(ankle[i]), atol=1e-5)
        foot_z = data.xmat[model.body("l_foot").id].reshape(3, 3)[:, 2]
        np.testing.assert_allclose(foot_z, [0.0, 0.0, 1.0], atol=1e-5)
