"""The thermal walk (gait-eval --horizon 600): temperatures sampled inside the rollout against
the exact two-node response, the first control step at the firmware limit, and the record of
a short NAO walk in the nominal world and in two test-stream worlds."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait.thermal_walk import leg_table, thermal_walk
from eaco_jax.problems.gait import make_gait_problem

# one joint: R_wh 4, R_ha 12 K/W, tau_w 10 s, tau_h 400 s; limit 75 C from 25 C
MM = mo.MotorModel(*(np.array([v], np.float64) for v in (
    100.0, 1.0, 0.02, 5.0, 0.5, 2.0, 0.8, 4.0, 12.0, 10.0, 400.0, 75.0, 25.0, 100.0)))


def _exact(t, power):
    c_w, c_h, r1, r2 = 10.0 / 4.0, 400.0 / 12.0, 4.0, 12.0
    aug = np.zeros((3, 3))
    aug[:2, :2] = [[-1 / (r1 * c_w), 1 / (r1 * c_w)], [1 / (r1 * c_h), -(1 / r1 + 1 / r2) / c_h]]
    aug[:2, 2] = [power / c_w, 0.0]
    return (expm(aug * t) @ np.array([0.0, 0.0, 1.0]))[:2]


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_trace_samples_the_exact_response_and_the_limit_crossing(xp):
    """20 W held (steady winding 320 K above ambient): samples every 50 control steps of 0.1 s
    (5 s) equal the matrix-exponential response; the first control step whose end is at or
    above the 50 K rise is the one containing the closed-form crossing. Fed in chunks of
    7 control steps, as the native backend does (MJX feeds one)."""
    el = ql.Electrics(MM, mo.modes(MM, 0.1), substeps=1, horizon=400, trace_every=50)
    acc = ql.new_acc((1,), 1, xp, motor=True, trace_samples=ql.trace_samples(el))
    assert acc["therm_trace"].shape == (1, 8, 1, 2)
    ones = np.ones((1, 400, 1), np.float32)
    for s in range(0, 400, 7):
        k = min(7, 400 - s)
        acc = ql.add_physics(acc, *(xp.asarray(a) for a in (
            0 * ones[:, :k], 2 * ones[:, :k], ones[:, :1], ones[:, :k, 0] > 0)),
            ql.MotorParams(kp=np.array([1e4]), stall=np.array([3.2]),
                           damping=np.array([0.0]), no_load_speed=np.array([10.0]),
                           nominal=np.array([1.0]), ctrl_lo=np.array([-1.0]),
                           ctrl_hi=np.array([1.0])), 0.1, xp, el=el, step0=s)
    # tau 3.2 driving at 2 rad/s -> 2 A -> 20 W copper loss
    trace = np.asarray(acc["therm_trace"])[0, :, 0]
    for i in range(8):
        np.testing.assert_allclose(trace[i], _exact(5.0 * (i + 1), 20.0), rtol=2e-5)
    t_hit = brentq(lambda t: _exact(t, 20.0)[0] - 50.0, 1e-6, 40.0)
    assert int(np.asarray(acc["hot_step"])[0, 0]) == int(np.ceil(t_hit / 0.1)) - 1


@pytest.fixture(scope="module")
def walk():
    p = make_gait_problem("nao", backend="native", horizon=2.0)
    return p, np.asarray(p.lower + 0.5 * (p.upper - p.lower))


def test_thermal_walk_nominal_record(walk):
    p, x = walk
    rec = thermal_walk(p, x, sample_s=0.5)
    assert rec["worlds"] == 1 and rec["stream"] == "nominal"
    assert rec["trace"]["t_s"] == [0.5, 1.0, 1.5, 2.0]
    knee = rec["joints"]["LKneePitch"]
    w = rec["trace"]["winding_c"]["LKneePitch"]
    assert 25.0 < w[0] < w[-1] == pytest.approx(knee["winding_end_c"], abs=1e-3)
    assert knee["housing_end_c"] < knee["winding_end_c"]
    assert knee["winding_steady_c"] > knee["winding_end_c"]
    assert rec["peak_current_max_frac"] <= 1.0 + 1e-5  # the limits are in the physics
    assert rec["fall_rate_ci95"][0] == 0.0 and rec["n"] == 1
    assert set(leg_table(rec)) == {"HipYawPitch", "HipRoll", "HipPitch", "KneePitch",
                                   "AnklePitch", "AnkleRoll"}


@pytest.mark.slow  # worlds through the native callback: about 30 s on 2 cores
def test_thermal_walk_in_test_stream_worlds(walk):
    p, x = walk
    rec = thermal_walk(p, x, n=2, seed=3, sample_s=1.0)
    assert rec["worlds"] == 2 and rec["stream"] == "test" and rec["n"] == 2
    assert len(rec["trace"]["winding_c"]["LKneePitch"]) == 2
    assert 0 <= rec["falls"] <= 2


@pytest.mark.slow  # compiles MJX's step with the worlds (about 2 min on 2 cores)
def test_thermal_walk_backends_agree():
    """The stored gait, 2 s, two test-stream worlds: the temperatures sampled inside MJX's scan
    and on the native backend agree (the same losses, the same thermal steps)."""
    import json

    best = json.loads(open("experiments/results/nao_best_gait.json").read())["vector"]
    recs = {b: thermal_walk(make_gait_problem("nao", backend=b, horizon=2.0), best, n=2,
                            seed=5, sample_s=0.5) for b in ("mjx", "native")}
    for name in ("RKneePitch", "LHipPitch", "RAnklePitch"):
        np.testing.assert_allclose(recs["mjx"]["trace"]["winding_c"][name],
                                   recs["native"]["trace"]["winding_c"][name], atol=0.2)
    assert recs["mjx"]["falls"] == recs["native"]["falls"]


def test_thermal_needs_electrical_motor_data():
    """--thermal on a robot without electrical motor data is one line naming the fix, before
    any simulation."""
    from eaco_jax.errors import ProblemError
    from eaco_jax.runs.gait import GaitEvalSettings, run_eval

    s = GaitEvalSettings(params_file="experiments/results/go2_cpu_gait.json", thermal=True,
                         horizon=1.0, backend="native")
    with pytest.raises(ProblemError, match="drop --thermal"):
        run_eval(s)


def test_walking_worlds_leave_the_fallen_out(walk):
    """The record's worst slip, drift and heat over every world include a fallen robot's slide;
    ``walking_worlds`` and the summary line give them over the worlds that walked."""
    from eaco_jax.gait import motors as mo
    from eaco_jax.gait.thermal_walk import _record
    from eaco_jax.runs.gait import thermal_line

    p, _ = walk
    nu = len(p.spec.joint_names)
    heat = np.stack([np.full(nu, 40.0), np.full(nu, 90.0)])
    heat[0, 3] = 50.0
    q = {"foot_slip_m": np.array([0.05, 5.0]), "winding_trace_c": heat[:, None, :],
         "housing_trace_c": heat[:, None, :] - 5.0, "limit_step": -np.ones((2, nu), int),
         "winding_end_c": heat, "housing_end_c": heat - 5.0, "copper_loss_w": np.ones((2, nu)),
         "peak_current_frac": np.full((2, nu), 0.5)}
    res = {"fell": np.array([False, True]), "distance_m": np.array([2.0, 0.5]),
           "speed_mps": np.array([0.1, 0.02]), "drift_deg": np.array([3.0, 60.0])}
    rec = _record(p, q, res, 2, 1, "test", 0, mo.motor_model(p.spec))
    assert rec["slip_per_m_max"] == pytest.approx(10.0) and rec["drift_deg_max"] == 60.0
    w = rec["walking_worlds"]
    assert w["worlds"] == 1 and w["slip_per_m_max"] == pytest.approx(0.025)
    assert w["drift_deg_max"] == 3.0 and w["winding_end_c_max"] == 50.0
    assert w["hottest_joint"] == p.spec.joint_names[3]
    assert "over the 1 walking worlds slip 0.025 m/m, drift 3.0 deg" in thermal_line(rec)
    res["fell"] = np.array([False, False])
    assert _record(p, q, res, 2, 1, "test", 0, mo.motor_model(p.spec))["walking_worlds"][
        "worlds"] == 2
