"""The walk engines on robots without the NAO's joint names (the Menagerie OP3): the standing
pose on a slope, the arm swing from the spec's ``arm_swing_joints``, the leg IK choice through
``make_gait_problem`` and the command line, the spec's ``feet`` and ``arm_swing_joints``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.legs import leg_set
from eaco_jax.gait.robot import ROBOTS_DIR, load_robot, stand_qpos


def _kinematics(spec, pose):
    """MuJoCo data after forward kinematics with the joints at ``pose`` (root standing)."""
    model = mujoco.MjModel.from_xml_path(spec.xml_path)
    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(spec, model)
    for name, v in zip(spec.joint_names, np.asarray(pose, np.float64), strict=True):
        data.qpos[model.joint(name).qposadr[0]] = v
    mujoco.mj_kinematics(model, data)
    return model, data


def _foot_pitch(spec, pose) -> list[float]:
    """Each foot's pitch about the torso's y axis (rad), legs in leg_set order."""
    model, data = _kinematics(spec, pose)
    torso = data.xmat[model.body(spec.torso_body).id].reshape(3, 3)
    out = []
    for foot in leg_set(spec).feet:
        rel = torso.T @ data.xmat[model.body(foot).id].reshape(3, 3)
        out.append(math.atan2(rel[0, 2], rel[2, 2]))
    return out


@pytest.mark.parametrize("robot", ["nao", "op3"])
def test_stand_pose_on_a_slope_turns_both_soles_with_the_floor(robot):
    spec = load_robot(robot)
    flat = _foot_pitch(spec, we.stand_pose(spec, 0.0))
    tilted = _foot_pitch(spec, we.stand_pose(spec, 5.0))
    # uphill along +x: each sole pitches nose-up by the slope (about -y), whatever the sign
    # of the robot's ankle axes (the OP3's left and right ankle-pitch axes are opposite)
    for a, b in zip(flat, tilted, strict=True):
        assert b - a == pytest.approx(-math.radians(5.0), abs=1e-6)
    np.testing.assert_array_equal(we.stand_pose(spec, 0.0), spec.stand_ctrl)


def _hand_x(spec, pose, joint) -> float:
    """x (torso frame) of the body two links below an arm-swing joint (the forearm)."""
    model, data = _kinematics(spec, pose)
    body = int(model.jnt_bodyid[model.joint(joint).id])
    child = [b for b in range(model.nbody) if model.body_parentid[b] == body][0]
    grand = [b for b in range(model.nbody) if model.body_parentid[b] == child] or [child]
    torso = model.body(spec.torso_body).id
    rel = data.xpos[grand[0]] - data.xpos[torso]
    return float((data.xmat[torso].reshape(3, 3).T @ rel)[0])


@pytest.mark.parametrize("robot", ["nao", "op3"])
def test_arms_swing_against_the_legs(robot):
    spec = load_robot(robot)
    lo, hi = (np.asarray(b) for b in we.bounds(spec, "generic"))
    p = (lo + hi) / 2
    names = we.PARAM_NAMES
    p[names.index("arm_swing")] = hi[names.index("arm_swing")]
    p[names.index("direction")] = p[names.index("turn_rate")] = 0.0
    period = float(p[names.index("period")])
    # a whole number of cycles after the ramp: phase 0, the left foot at its front end
    t = jnp.float32((math.ceil(we.RAMP_TIME / period) + 1) * period)
    q = np.asarray(we.joint_targets(jnp.asarray(p), t, spec, ik="generic"))
    feet = we.biped_feet(jnp.asarray(p), t, spec)
    assert float(feet.delta[0, 0]) > 0.01 > -0.01 > float(feet.delta[1, 0])  # left ahead
    left, right = spec.arm_swing_joints
    stand = np.asarray(spec.stand_ctrl)
    assert _hand_x(spec, q, left) < _hand_x(spec, stand, left) - 0.005  # left arm back
    assert _hand_x(spec, q, right) > _hand_x(spec, stand, right) + 0.005  # right arm forward


def test_problem_controls_use_its_ik():
    from eaco_jax.problems.gait import make_gait_problem

    generic = make_gait_problem("nao", backend="native", horizon=1.2, ik="generic")
    analytic = make_gait_problem("nao", backend="native", horizon=1.2, ik="analytic")
    x = (generic.lower + generic.upper)[None] / 2
    cg = np.asarray(jax.jit(generic.controls)(x))
    ca = np.asarray(jax.jit(analytic.controls)(x))
    for problem, got in ((generic, cg), (analytic, ca)):
        want = jax.jit(jax.vmap(lambda p, ik=problem.ik: we.control_sequence(
            p, generic.n_steps, generic.spec, ik=ik)))(x)
        np.testing.assert_array_equal(got, np.asarray(want))
    assert not np.array_equal(cg, ca)  # the two IKs agree closely, not bit for bit
    np.testing.assert_allclose(cg, ca, atol=1e-4)
    with pytest.raises(ConfigError, match="use ik='generic'"):
        make_gait_problem("op3", backend="native", horizon=1.0, ik="analytic")
    with pytest.raises(ProblemError, match="ik must be one of"):
        make_gait_problem("go2", backend="native", horizon=1.0, ik="numeric")


def test_op3_gait_and_gait_eval_from_the_command_line(tmp_path):
    out = tmp_path / "op3"
    res = CliRunner().invoke(app, ["gait", "--robot", "op3", "--ik", "generic", "--backend",
                                   "native", "--ants", "4", "--iterations", "1", "--horizon",
                                   "0.5", "--no-video", "--out", str(out), "--json"])
    assert res.exit_code == 0, (res.output, res.exception)
    record = json.loads(res.stdout.strip().splitlines()[-1])
    assert record["robot"] == "op3" and record["ik"] == "generic"
    res = CliRunner().invoke(app, ["gait-eval", str(out / "best_gait.json"), "--backend",
                                   "native", "--json"])
    assert res.exit_code == 0, (res.output, res.exception)
    again = json.loads(res.stdout.strip().splitlines()[-1])
    assert again["ik"] == "generic"
    assert again["fitness"] == pytest.approx(record["fitness"], abs=1e-6)
    res = CliRunner().invoke(app, ["gait", "--robot", "op3", "--ik", "analytic", "--backend",
                                   "native", "--ants", "4", "--iterations", "1", "--no-video",
                                   "--out", str(tmp_path / "bad")])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "ik='generic'" in lines[0]


def _op3_spec(tmp_path: Path, **fields) -> Path:
    raw = json.loads((ROBOTS_DIR / "op3.json").read_text())
    raw["xml"] = str(ROBOTS_DIR / raw["xml"])
    raw.update(fields)
    path = tmp_path / "op3_mine.json"
    path.write_text(json.dumps(raw))
    return path


def test_spec_feet_name_the_leg_ends(tmp_path):
    spec = load_robot(_op3_spec(tmp_path, feet=["l_ank_roll_link", "r_ank_roll_link"]))
    assert spec.feet == ("l_ank_roll_link", "r_ank_roll_link")
    legs = leg_set(spec)
    assert legs.feet == spec.feet and legs.joint_index.shape == (2, 6)
    default = leg_set(load_robot("op3"))
    # the body origin (the ankle) sits above the soles' centroid, the default foot point
    assert np.all(legs.stand_pos[:, 2] > default.stand_pos[:, 2])


BAD_FIELDS = {
    "feet not in the MJCF": ({"feet": ["l_toe", "r_ank_roll_link"]}, "feet[0] 'l_toe'"),
    "feet not names": ({"feet": "l_ank_roll_link"}, "field 'feet'"),
    "arm joint unknown": ({"arm_swing_joints": ["l_sho_pitch", "r_shoulder"]},
                          "arm_swing_joints[1] 'r_shoulder'"),
    "one arm": ({"arm_swing_joints": ["l_sho_pitch"]}, "arm_swing_joints must be two"),
}


@pytest.mark.parametrize("case", sorted(BAD_FIELDS))
def test_bad_feet_and_arm_fields_are_one_line(tmp_path, case):
    fields, fragment = BAD_FIELDS[case]
    with pytest.raises(ProblemError) as err:
        load_robot(_op3_spec(tmp_path, **fields))
    assert fragment in str(err.value) and "\n" not in str(err.value)


def test_arm_swing_joint_must_turn_sideways(tmp_path):
    spec = load_robot(_op3_spec(tmp_path, arm_swing_joints=["l_sho_roll", "r_sho_roll"]))
    with pytest.raises(ProblemError, match="does not turn about the torso's y axis"):
        we.joint_targets(jnp.asarray((np.asarray(we.bounds(spec)[0]) +
                                      np.asarray(we.bounds(spec)[1])) / 2),
                         jnp.float32(0.5), spec)


def _go2_without_motors(tmp_path) -> str:
    """The Go2's spec less its ``motors`` block, in ``tmp_path``: a robot without motor data."""
    raw = json.loads((ROBOTS_DIR / "go2.json").read_text())
    raw.pop("motors")
    raw["xml"] = str(ROBOTS_DIR / "unitree_go2" / "scene.xml")
    path = tmp_path / "go2_plain.json"
    path.write_text(json.dumps(raw))
    return str(path)


def test_robust_worlds_and_trials_without_a_motor_datasheet(tmp_path):
    from eaco_jax.gait.validate import evaluate_trials
    from eaco_jax.problems.gait import RobustConfig, make_gait_problem

    plain = _go2_without_motors(tmp_path)
    problem = make_gait_problem(plain, backend="native", horizon=0.6,
                                robust=RobustConfig(R=2, seed=5))
    assert not problem.spec.has_motors
    x = jnp.asarray(np.stack([problem.lower, problem.upper]) * 0.5 + 0.25 * (
        problem.lower + problem.upper))
    f = np.asarray(problem.evaluate(x, jax.random.PRNGKey(1)).f)
    assert f.shape == (2,) and np.all(np.isfinite(f))
    trials = evaluate_trials(problem, np.asarray(x[0]), n=4, seed=5)
    assert trials["n"] == 4 and 0 <= trials["falls"] <= 4
    assert math.isnan(trials["mean_power_w_mean"])  # energy needs a datasheet
    assert trials["speed_mps_ci95"] > 0.0  # the worlds differ
    with pytest.raises(ProblemError, match="energy penalty needs one"):
        make_gait_problem(plain, backend="native", horizon=0.6, penalty="cot")


@pytest.mark.parametrize("robot,ankle", [("nao", "LAnklePitch"), ("op3", "l_ank_pitch")])
def test_joint_angle_plot_shows_each_legs_sagittal_joints(robot, ankle):
    from eaco_jax.runs.gait import leg_joints

    spec = load_robot(robot)
    angles, groups = leg_joints({n: np.full(3, i) for i, n in enumerate(spec.joint_names)},
                                spec)
    assert groups == ("Hip", "Knee", "Ankle") and len(angles) == 6
    for group in groups:  # plots.joint_trajectories: a joint goes to each panel it names
        assert sum(group.lower() in label.lower() for label in angles) == 2
    label = next(k for k in angles if k.endswith(ankle))
    assert "ankle" in label.lower() and angles[label][0] == spec.joint_names.index(ankle)
