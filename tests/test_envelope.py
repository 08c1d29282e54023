"""The actuator envelope (eaco_jax.gait.quality.envelope): hand-computed rows for a constructed
torque trace, with and without motor data; the NAO's envelope agrees with its quality record
(the numbers gait-eval printed before the envelope existed); gait-eval prints and records the
envelope of the Menagerie robots against their motor data, and the reduced one for a robot
without."""

import json
import math
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.gait import quality as ql
from eaco_jax.gait.robot import ROBOTS_DIR, load_robot

MP = ql.MotorParams(kp=np.array([100.0, 100.0]), stall=np.array([8.0, 4.0]),
                    damping=np.array([1.0, 0.5]), no_load_speed=np.array([8.0, 4.0]),
                    nominal=np.array([2.0, 1.0]), ctrl_lo=np.array([-1.0, -1.0]),
                    ctrl_hi=np.array([1.0, 1.0]), kd=np.array([0.5, 2.0]))
NAMES = ("a", "b")


def _trace(xp):
    """Two live physics steps and one after the fall (B=1, S=3, nu=2).

    joint a: servo 100 (1 - 0) - 0.5 qdot saturates at 8; tau = 8 - 1 qdot = 6 (qdot 2), 7
    (qdot 1): peak 7, RMS sqrt((36 + 49) / 2), peak speed 2.
    joint b: servo 100 (0 - 0.01) - 2 qdot = -3 (inside +-4); tau = -3 - 0.5 = -3.5 both steps:
    peak = RMS = 3.5, peak speed 1. The third step (qdot 5) is after the fall: not counted.
    """
    q = np.array([[[0.0, 0.01]] * 3], np.float32)
    qdot = np.array([[[2.0, 1.0], [1.0, 1.0], [5.0, 5.0]]], np.float32)
    ctrl = np.array([[[1.0, 0.0]]], np.float32)
    alive = np.array([[True, True, False]])
    acc = ql.add_physics(ql.new_acc((1,), 2, xp), xp.asarray(q), xp.asarray(qdot),
                         xp.asarray(ctrl), xp.asarray(alive), MP, 0.01, xp)
    return ql.finalize(jax.tree.map(jnp.asarray, acc), jnp.array([0.1]), 5.0, 0.01,
                       jnp.asarray(MP.nominal))


def _spec(motors: bool):
    return SimpleNamespace(
        joint_names=NAMES, nu=2, has_motors=motors, nominal_torque=(2.0, 1.0),
        stall_torque=(10.0, 4.0), no_load_speed=(8.0, 4.0), force_limit=(8.0, math.inf))


def _eaco(args: list[str]):
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    return res


RMS_A = math.sqrt((36.0 + 49.0) / 2.0)


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_envelope_rows_with_motor_data(xp):
    env = ql.envelope(_trace(xp), _spec(True))
    a, b = env["joints"]["a"], env["joints"]["b"]
    assert a["rms_torque_nm"] == pytest.approx(RMS_A, rel=1e-6)
    assert a["peak_torque_nm"] == pytest.approx(7.0, rel=1e-6)
    assert a["peak_speed_rad_s"] == pytest.approx(2.0)
    assert a["rms_torque_frac"] == pytest.approx(RMS_A / 2.0, rel=1e-6)
    assert a["peak_torque_frac"] == pytest.approx(0.7, rel=1e-6)  # the datasheet's 10, not 8
    assert a["peak_speed_frac"] == pytest.approx(0.25)
    assert b["rms_torque_nm"] == pytest.approx(3.5, rel=1e-6)
    assert b["peak_torque_nm"] == pytest.approx(3.5, rel=1e-6)
    assert b["peak_speed_rad_s"] == pytest.approx(1.0)
    assert b["rms_torque_frac"] == pytest.approx(3.5, rel=1e-6)
    assert b["peak_torque_frac"] == pytest.approx(3.5 / 4.0, rel=1e-6)
    assert b["peak_speed_frac"] == pytest.approx(0.25)
    assert env["worst"]["rms_torque_frac"]["joint"] == "b"
    assert env["worst"]["peak_torque_frac"]["joint"] == "b"
    assert env["overheating"] == ["a", "b"]
    assert env["limits"]["a"] == {"rms_nm": 2.0, "peak_nm": 10.0, "speed_rad_s": 8.0}
    table = ql.envelope_table(env)
    assert "/nominal" in table and "overheating: a, b" in table


def test_reduced_envelope_without_motor_data():
    env = ql.envelope(_trace(np), _spec(False))
    a, b = env["joints"]["a"], env["joints"]["b"]
    assert a["rms_torque_frac"] == pytest.approx(RMS_A / 8.0, rel=1e-6)  # / forcerange
    assert a["peak_torque_frac"] == pytest.approx(7.0 / 8.0, rel=1e-6)
    assert a["peak_speed_frac"] is None and b["peak_speed_frac"] is None  # no speed limit
    assert b["rms_torque_frac"] is None and b["peak_torque_frac"] is None  # unlimited force
    assert b["peak_torque_nm"] == pytest.approx(3.5, rel=1e-6)
    assert env["overheating"] == [] and env["worst"]["peak_speed_frac"] is None
    assert env["limits"]["b"] == {"rms_nm": None, "peak_nm": None, "speed_rad_s": None}
    assert "/force" in ql.envelope_table(env)


def test_nao_envelope_agrees_with_its_quality_record():
    from eaco_jax.problems.gait import make_gait_problem

    p = make_gait_problem("nao", backend="native", horizon=1.0)
    vec = json.loads(Path("experiments/results/nao_best_gait.json").read_text())["vector"]
    sim = p.simulate(np.asarray(vec), record=False)
    q, env = sim["quality"], sim["envelope"]
    assert set(env["joints"]) == set(q["rms_torque_frac"])
    for j, row in env["joints"].items():
        assert row["rms_torque_frac"] == pytest.approx(q["rms_torque_frac"][j], rel=1e-5)
    peak = max(r["peak_torque_frac"] for r in env["joints"].values())
    speed = max(r["peak_speed_frac"] for r in env["joints"].values())
    # the NAO's forcerange is its stall torque, rounded in nao.xml (relative 1e-4)
    assert peak == pytest.approx(q["peak_torque_frac"], rel=1e-3)
    assert speed == pytest.approx(q["peak_speed_frac"], rel=1e-5)
    assert env["overheating"] == q["overheating"]


@pytest.mark.parametrize("robot,joint,stall,speed", [
    ("go2", "RL_calf_joint", 35.55, 30.1 / 1.5), ("op3", "l_knee", 3.8, 43 * 2 * math.pi / 60)])
def test_gait_eval_records_menagerie_envelope(tmp_path, robot, joint, stall, speed):
    out = tmp_path / "eval"
    res = _eaco(["gait-eval", f"experiments/results/{robot}_cpu_gait.json", "--backend",
                 "native", "--horizon", "0.4", "--no-video", "--out", str(out)])
    assert "actuator envelope (motor data" in res.stdout
    env = json.loads((out / "gait_eval.json").read_text())["envelope"]
    assert env["motor_data"]
    assert env["limits"][joint]["peak_nm"] == pytest.approx(stall, rel=1e-4)
    assert env["limits"][joint]["speed_rad_s"] == pytest.approx(speed, rel=2e-3)
    row = env["joints"][joint]
    assert row["peak_torque_frac"] == pytest.approx(row["peak_torque_nm"] / stall, rel=1e-4)


def test_reduced_envelope_of_a_spec_without_motor_data(tmp_path):
    raw = json.loads((ROBOTS_DIR / "go2.json").read_text())
    raw.pop("motors")
    raw["xml"] = str(ROBOTS_DIR / "unitree_go2" / "scene.xml")
    spec = tmp_path / "go2_plain.json"
    spec.write_text(json.dumps(raw))
    assert not load_robot(spec).has_motors
    gait = json.loads(Path("experiments/results/go2_cpu_gait.json").read_text())
    gait.pop("robot", None)
    gait_file = tmp_path / "gait.json"
    gait_file.write_text(json.dumps(gait))
    text = _eaco(["gait-eval", str(gait_file), "--robot", str(spec), "--backend", "native",
                  "--horizon", "0.4", "--no-video"]).stdout
    assert "no motor data" in text and "/force" in text and "FR_calf_joint" in text
