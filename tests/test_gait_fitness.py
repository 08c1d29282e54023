"""The paper's gait fitness rules, on constructed traces and on real (native) physics."""

import math

import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.fitness import gait_fitness, summarize
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_native import initial_state, native_model, native_trace, root_trace

DT = 0.02


def _trace(xy_end, n=101, fall_at=None, z=0.3):
    """Straight-line torso trace from the origin to ``xy_end``; optional fall at row fall_at."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    pos = np.concatenate([s * np.asarray(xy_end)[None], np.full((n, 1), z)], 1)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    if fall_at is not None:
        pos[fall_at:, 2] = 0.05
    return jnp.asarray(pos, jnp.float32), jnp.asarray(up, jnp.float32)


def _fit(pos, up, direction=0.0, slope=0.0):
    out = gait_fitness(summarize(pos, up, DT, 0.2, 50.0, slope), direction)
    return {k: float(v) for k, v in out.items()}


def test_walking_forward_counts_distance():
    f = _fit(*_trace([2.0, 0.1]))
    assert f["fitness"] == pytest.approx(2.0, abs=1e-5)
    assert f["speed_mps"] == pytest.approx(1.0, abs=1e-5)
    assert f["fell"] == 0.0 and f["drift_deg"] == pytest.approx(math.degrees(math.atan(0.05)))


def test_backwards_sideways_and_still_give_zero():
    assert _fit(*_trace([-1.0, 0.0]))["fitness"] == 0.0
    assert _fit(*_trace([0.5, 0.6]))["fitness"] == 0.0  # drift 50 deg > 45
    assert _fit(*_trace([0.5, 0.45]))["fitness"] > 0.0  # drift 42 deg is fine
    assert _fit(*_trace([0.0, 0.0]))["fitness"] == 0.0


def test_desired_direction_is_respected():
    pos, up = _trace([0.0, 1.0])
    assert _fit(pos, up, direction=90.0)["fitness"] == pytest.approx(1.0, abs=1e-5)
    assert _fit(pos, up, direction=0.0)["fitness"] == 0.0


def test_fall_rules():
    # falls after 0.5 m (row 50 of 100): the distance until the fall counts
    f = _fit(*_trace([1.0, 0.0], fall_at=50))
    assert f["fell"] == 1.0 and f["fitness"] == pytest.approx(0.5, abs=1e-5)
    # falls after 5 cm: below the 10 cm rule -> 0
    f = _fit(*_trace([0.1, 0.0], fall_at=50))
    assert f["fell"] == 1.0 and f["fitness"] == 0.0
    # tilted torso is a fall too
    pos, up = _trace([1.0, 0.0])
    up = up.at[80:].set(jnp.array([0.9, 0.0, 0.43]))
    assert _fit(pos, up)["fitness"] == pytest.approx(0.8, abs=1e-5)


def test_nan_physics_gives_zero_not_nan():
    pos, up = _trace([1.0, 0.0])
    f = _fit(pos.at[40, 0].set(jnp.nan), up)
    assert f["fitness"] == 0.0 and all(np.isfinite(v) for v in f.values())


def test_slope_height_is_relative_to_the_floor():
    # 2 m uphill on a 10 degree slope: the floor rises 0.35 m; torso follows at 0.3 above it
    n = 101
    x = np.linspace(0, 2.0, n)
    pos = np.stack([x, 0 * x, 0.3 + x * math.tan(math.radians(10))], 1)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    f = _fit(jnp.asarray(pos), jnp.asarray(up), slope=10.0)
    assert f["fell"] == 0.0 and f["fitness"] == pytest.approx(2.0, abs=1e-5)


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def test_robot_pushed_over_falls(nao):
    """Real physics: a hard shove on the torso makes the standing robot fall -> fell, 0."""
    model = native_model(nao, 0.0, "fast")
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, initial_state(nao, model, 0.0),
                       mujoco.mjtState.mjSTATE_FULLPHYSICS)
    data.ctrl[:] = nao.stand_ctrl
    k = int(round(nao.control_dt / model.opt.timestep))
    torso = model.body(nao.torso_body).id
    rows = [root_trace(data.qpos[:7].copy())]
    for i in range(100):  # 2 s
        data.xfrc_applied[torso, 0] = 40.0 if i < 5 else 0.0  # 0.1 s push forward
        mujoco.mj_step(model, data, nstep=k)
        rows.append(root_trace(data.qpos[:7].copy()))
    tr = jnp.asarray(np.stack(rows))
    s = summarize(tr[:, :3], tr[:, 3:6], nao.control_dt, nao.fall_height, nao.fall_tilt_deg)
    f = {k: float(v) for k, v in gait_fitness(s).items()}
    assert f["fell"] == 1.0
    expected = f["distance_m"] if f["distance_m"] > 0.10 else 0.0
    assert f["fitness"] == pytest.approx(expected)


def test_real_walk_backwards_and_sideways(nao):
    """Real physics: the same gait stepped backwards / sideways scores 0 for 'forward'."""
    v = dict(zip(we.PARAM_NAMES, (we.LOWER + we.UPPER) / 2, strict=True))
    v.update(step_length=0.04, hip_height=0.21, duty_ratio=0.6, period=0.4, foot_lift=0.02,
             step_width=0.0, lateral_sway=0.0, torso_pitch=0.0, arm_swing=0.0,
             hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
             turn_rate=0.0)
    p = jnp.asarray([v[n] for n in we.PARAM_NAMES], jnp.float32)
    steps = int(round(2.0 / nao.control_dt))
    headings = [0.0, math.pi, math.pi / 2]
    ctrl = np.stack([np.asarray(we.control_sequence(p, steps, nao, h)) for h in headings])
    tr = jnp.asarray(native_trace(ctrl, nao))
    s = summarize(tr[..., :3], tr[..., 3:6], nao.control_dt, nao.fall_height, nao.fall_tilt_deg)
    forward = gait_fitness(s, 0.0)
    assert float(forward["distance_m"][0]) > 0.05
    assert float(forward["distance_m"][1]) < 0.0 and float(forward["fitness"][1]) == 0.0
    assert float(forward["drift_deg"][2]) > 45.0 and float(forward["fitness"][2]) == 0.0
    # sideways walking is fine when sideways is the desired direction
    left = gait_fitness(s, 90.0)
    assert float(left["drift_deg"][2]) < 45.0


def _turning(total_deg, n=101, fall_at=None):
    """Torso turning in place by ``total_deg`` (several turns unwrap), optional fall."""
    pos, up = _trace([0.0, 0.0], n, fall_at)
    yaw = np.radians(np.linspace(0.0, total_deg, n))
    yaw = (yaw + np.pi) % (2 * np.pi) - np.pi  # as atan2 reports it
    return pos, up, jnp.asarray(yaw, jnp.float32)


def _turn_fit(pos, up, yaw, turn):
    out = gait_fitness(summarize(pos, up, DT, 0.2, 50.0, yaw=yaw), 0.0, turn)
    return {k: float(v) for k, v in out.items()}


def test_turning_scores_the_heading_turned_unwrapped():
    pos, up, yaw = _turning(500.0)  # more than a full turn: the wrap must not lose it
    left = _turn_fit(pos, up, yaw, "left")
    assert left["fitness"] == pytest.approx(500.0, abs=0.1)
    assert left["turn_deg_s"] == pytest.approx(500.0 / 2.0, abs=0.1)
    assert _turn_fit(pos, up, yaw, "right")["fitness"] == 0.0  # the other way
    assert _turn_fit(*_turning(-90.0), "right")["fitness"] == pytest.approx(90.0, abs=0.1)
    # walking straight: the distance rule, as before (turning is only scored when asked)
    assert _turn_fit(pos, up, yaw, None)["fitness"] == 0.0


def test_turning_fall_rule():
    """A fall keeps the heading turned before it only above FALL_MIN_TURN_DEG."""
    from eaco_jax.gait.fitness import FALL_MIN_TURN_DEG

    big = _turn_fit(*_turning(100.0, fall_at=51), "left")  # 51 deg turned by row 51
    assert big["fell"] == 1.0 and big["fitness"] == pytest.approx(51.0, abs=0.1)
    small = _turn_fit(*_turning(2 * FALL_MIN_TURN_DEG - 10, fall_at=51), "left")
    assert small["fell"] == 1.0 and small["fitness"] == 0.0


def test_heading_column_matches_the_body_on_native_physics():
    """The trace's 7th column is the torso's yaw: a robot turned by 30 degrees reads 30."""
    nao = load_robot("nao")
    model = native_model(nao, 0.0, "fast")
    data = mujoco.MjData(model)
    q = np.array(initial_state(nao, model, 0.0)[1:8])
    half = math.radians(30.0) / 2
    q[3:7] = [math.cos(half), 0.0, 0.0, math.sin(half)]
    row = root_trace(q)
    assert row.shape == (7,) and math.degrees(row[6]) == pytest.approx(30.0, abs=1e-4)
    assert row[5] == pytest.approx(1.0, abs=1e-6)  # still upright
    del data
