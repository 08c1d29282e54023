"""Robot models: the NAO-scale humanoid loads with NAO V5 size, mass and joints and stands still;
the robot registry gives clear errors; brax's ant loads as a second robot."""

import mujoco
import numpy as np
import pytest

from eaco_jax.gait.robot import known_robots, load_model, load_robot, stand_qpos
from eaco_jax.gait.rollout_native import native_trace


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def test_nao_model_matches_nao_specs(nao):
    model = load_model(nao)
    assert model.nu == 22 and len(nao.joint_names) == 22
    assert sum(model.body_mass) == pytest.approx(5.25, abs=0.05)  # NAO V4/V5 link masses
    data = mujoco.MjData(model)
    data.qpos[3] = 1.0
    data.qpos[2] = nao.geom("thigh") + nao.geom("tibia") + nao.geom("foot_height") \
        + nao.geom("hip_offset_z")
    mujoco.mj_kinematics(model, data)
    head = model.geom("head_geom")
    top = data.geom_xpos[head.id][2] + head.size[0]
    assert top == pytest.approx(0.57, abs=0.01)  # standing height with straight legs
    # only the soles can touch the floor
    touching = [model.geom(i).name for i in range(model.ngeom)
                if model.geom_contype[i] or model.geom_conaffinity[i]]
    assert sorted(touching) == sorted(["floor", *nao.foot_geoms])
    # NAO knee range and the position actuators' limits
    knee = model.joint("LKneePitch")
    assert np.degrees(knee.range[1]) == pytest.approx(121.04, abs=0.1)
    assert np.all(model.actuator_forcerange[:, 1] > 0)


def test_nao_stands_still_for_one_second_native(nao):
    steps = int(round(1.0 / nao.control_dt))
    controls = np.tile(np.asarray(nao.stand_ctrl), (1, steps, 1))
    trace = native_trace(controls, nao)
    start, end = trace[0, 0], trace[0, -1]
    assert np.linalg.norm(end[:2] - start[:2]) < 0.01
    assert abs(end[2] - nao.nominal_torso_height) < 0.01
    assert end[5] > 0.99  # upright


def test_slope_tilts_the_floor(nao):
    model = load_model(nao, slope_deg=5.0)
    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(nao, model)
    mujoco.mj_kinematics(model, data)
    normal = data.geom_xmat[model.geom("floor").id].reshape(3, 3)[:, 2]
    assert np.degrees(np.arccos(normal[2])) == pytest.approx(5.0, abs=1e-4)
    assert normal[0] < 0  # uphill toward +x


def test_registry_errors_and_ant():
    assert {"nao", "ant"} <= set(known_robots())
    with pytest.raises(ValueError, match="known robots: ant, .*nao"):
        load_robot("atlas")
    ant = load_robot("ant")
    model = load_model(ant)
    assert model.nu == 8 == ant.nu
    # motors were replaced by position servos: holding the standing targets keeps it up
    steps = int(round(1.0 / ant.control_dt))
    trace = native_trace(np.tile(np.asarray(ant.stand_ctrl), (1, steps, 1)), ant)
    assert trace[0, -1, 5] > 0.9 and trace[0, -1, 2] > ant.fall_height
