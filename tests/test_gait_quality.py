"""Energy and gait-quality metrics: the accumulators on constructed cases (numpy and JAX give the
same), and on real physics (a slow walk): plausible values, the same on both backends, and the
optional energy penalty lowers the fitness."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.gait import quality as ql
from eaco_jax.gait import walk_engine as we
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.gait import make_gait_problem

NU = 2
MP = ql.MotorParams(kp=np.array([100.0, 100.0]), stall=np.array([8.0, 4.0]),
                    damping=np.array([1.0, 0.5]), no_load_speed=np.array([8.0, 8.0]),
                    nominal=np.array([2.0, 1.0]), ctrl_lo=np.array([-1.0, -1.0]),
                    ctrl_hi=np.array([1.0, 1.0]))


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_physics_accumulators_on_a_constructed_case(xp):
    # joint 0: saturated servo (force 8) moving at 2 rad/s -> tau = 8 - 1 * 2 = 6, power 12 W
    # joint 1: force 100 * (0 - 0.01) = -1 at +1 rad/s -> tau = -1.5, power 0 (negative work)
    q = np.array([[[0.0, 0.01]] * 3], np.float32)  # (B=1, S=3, nu)
    qdot = np.array([[[2.0, 1.0]] * 3], np.float32)
    ctrl = np.array([[[1.0, 0.0]]], np.float32)
    alive = np.array([[True, True, False]])  # the third step is after a fall
    acc = ql.add_physics(ql.new_acc((1,), NU, xp), xp.asarray(q), xp.asarray(qdot),
                         xp.asarray(ctrl), xp.asarray(alive), MP, 0.01, xp)
    assert float(acc["energy"][0]) == pytest.approx(2 * 12.0 * 0.01)
    assert float(acc["peak_power"][0]) == pytest.approx(12.0)
    assert float(acc["steps"][0]) == 2
    np.testing.assert_allclose(np.asarray(acc["peak_speed"][0]), [2 / 8, 1 / 8], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(acc["peak_torque"][0]), [6 / 8, 1.5 / 4], rtol=1e-6)
    out = ql.finalize(jax.tree.map(jnp.asarray, acc), jnp.array([0.1]), 5.0, 0.01,
                      jnp.asarray(MP.nominal))
    assert float(out["mean_power_w"][0]) == pytest.approx(12.0)
    assert float(out["cost_of_transport"][0]) == pytest.approx(0.24 / (5.0 * 9.81 * 0.1))
    np.testing.assert_allclose(np.asarray(out["rms_torque_frac"][0]), [6 / 2, 1.5 / 1], rtol=1e-6)
    assert ql.overheating(out["rms_torque_frac"], ["a", "b"]) == ["a", "b"]
    still = ql.finalize(jax.tree.map(jnp.asarray, acc), jnp.array([0.0]), 5.0, 0.01,
                        jnp.asarray(MP.nominal))
    assert np.isnan(float(still["cost_of_transport"][0]))  # no distance: no CoT


def _feet(left_xy, right_xy, left_z, right_z):
    """Sole spheres (8, 3): four per foot at +-2 cm around the foot centre."""
    off = np.array([[0.02, 0.02], [0.02, -0.02], [-0.02, 0.02], [-0.02, -0.02]])
    left = np.concatenate([np.asarray(left_xy) + off, np.full((4, 1), left_z)], 1)
    right = np.concatenate([np.asarray(right_xy) + off, np.full((4, 1), right_z)], 1)
    return np.concatenate([left, right])


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_control_accumulators_on_a_constructed_case(xp):
    r = 0.008
    steps = np.stack([
        _feet([0, 0.05], [0, -0.05], r, r),  # both down
        _feet([0.01, 0.05], [0, -0.05], r, r),  # left slid 1 cm in contact
        _feet([0.05, 0.05], [0, -0.05], 0.05, r),  # left lifted and moved: no slip
        _feet([0.05, 0.05], [0.05, -0.05], 0.05, 0.05),  # airborne
        _feet([0.05, 0.0], [0.05, -0.03], r, r),  # feet close: nearest spheres 1 cm apart
    ])[None].astype(np.float32)
    alive = np.ones((1, 5), bool)
    acc = ql.new_acc((1,), NU, xp)
    for i in range(5):  # one control step at a time (MJX) ...
        acc = ql.add_control(acc, xp.asarray(steps[:, i:i + 1]), xp.asarray(alive[:, i:i + 1]),
                             np.array([0, 0, 1.0]), r, xp)
    whole = ql.add_control(ql.new_acc((1,), NU, xp), xp.asarray(steps), xp.asarray(alive),
                           np.array([0, 0, 1.0]), r, xp)  # ... or a chunk at once (native)
    for a in (acc, whole):
        assert float(a["slip"][0]) == pytest.approx(0.01, abs=1e-6)
        assert float(a["air_steps"][0]) == 1 and float(a["ctrl_steps"][0]) == 5
        assert float(a["min_gap"][0]) == pytest.approx(0.01 - 2 * ql.FOOT_EDGE, abs=1e-6)



def _posed(rot, pivot, shift=(0.0, 0.0)):
    """One foot's four sole spheres (4, 3) of :func:`_feet`'s layout, flat at the radius, rotated
    by the matrix ``rot`` about the point ``pivot`` and moved by ``shift`` horizontally."""
    r = 0.008
    off = np.array([[0.02, 0.02, r], [0.02, -0.02, r], [-0.02, 0.02, r], [-0.02, -0.02, r]])
    pts = (off - pivot) @ np.asarray(rot).T + pivot
    return pts + np.array([shift[0], shift[1], 0.0])


def _rot(axis, a):
    c, s = np.cos(a), np.sin(a)
    return {"y": [[c, 0, -s], [0, 1, 0], [s, 0, c]], "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]


FAR = np.array([[0.0, -0.2, 0.5]] * 4)  # the other foot, in the air


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
@pytest.mark.parametrize("case,expect", [
    ("slide", 0.01),  # flat, every sphere slides 1 cm
    ("roll_heel", 0.0),  # heel-to-toe: the toe lifts 0.5 rad about the heel spheres' line
    ("pivot", 0.0),  # yaw 0.3 rad about one sphere
    ("air", 0.0),  # moving 5 cm a few cm above the floor
    ("landing", 0.0),  # in the air, then down 3 cm further on
])
def test_slip_is_the_contact_points_sliding(xp, case, expect):
    eye, heel = np.eye(3), np.array([-0.02, 0.0, 0.008])
    a, b = {
        "slide": (_posed(eye, heel), _posed(eye, heel, (0.01, 0.0))),
        "roll_heel": (_posed(eye, heel), _posed(_rot("y", 0.5), heel)),
        "pivot": (_posed(eye, heel), _posed(_rot("z", 0.3), np.array([-0.02, -0.02, 0.0]))),
        "air": (_posed(eye, heel) + [0, 0, 0.03], _posed(eye, heel, (0.05, 0)) + [0, 0, 0.03]),
        "landing": (_posed(eye, heel) + [0, 0, 0.03], _posed(eye, heel, (0.03, 0.0))),
    }[case]
    soles = np.stack([np.concatenate([a, FAR]), np.concatenate([b, FAR])])[None]
    acc = ql.add_control(ql.new_acc((1,), NU, xp), xp.asarray(soles.astype(np.float32)),
                         xp.asarray(np.ones((1, 2), bool)), np.array([0, 0, 1.0]), 0.008, xp)
    assert float(acc["slip"][0]) == pytest.approx(expect, abs=1e-6)
    centre = np.linalg.norm(b[:, :2].mean(0) - a[:, :2].mean(0))
    if case in ("roll_heel", "pivot"):  # the foot's centre moves: what the figure no longer counts
        assert centre > 2e-3

def _slow_walk(**kw):
    g = dict(step_length=0.06, hip_height=0.21, duty_ratio=0.6, period=0.5, foot_lift=0.02,
             step_width=0.01, lateral_sway=0.02, torso_pitch=0.05, arm_swing=0.3,
             hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
             turn_rate=0.0)
    g.update(kw)
    return [g[n] for n in we.PARAM_NAMES]


def test_walking_quality_is_plausible_native():
    p = make_gait_problem("nao", backend="native", horizon=3.0)
    sim = p.simulate(_slow_walk(), record=False)
    q = sim["quality"]
    assert not sim["fell"] and sim["distance_m"] > 0.3
    assert 1.0 < q["mean_power_w"] < q["peak_power_w"] < 150.0  # NAO legs peak near 150 W
    assert q["energy_j"] == pytest.approx(q["mean_power_w"] * 3.0, rel=1e-3)
    assert 0.1 < q["cost_of_transport"] < 10.0
    assert 0.3 < q["peak_speed_frac"] <= 1.05 and 0.3 < q["peak_torque_frac"] < 1.2
    assert q["airborne_fraction"] == 0.0  # duty ratio 0.6: always a foot down
    assert 0.0 < q["min_foot_gap_m"] < 0.05 and 0.0 <= q["foot_slip_m"] < 0.5
    assert set(q["rms_torque_frac"]) == set(p.spec.joint_names)
    assert q["rms_torque_frac"]["LKneePitch"] > q["rms_torque_frac"]["HeadYaw"]
    assert all(q["rms_torque_frac"][j] > 1.0 for j in q["overheating"])
    # a faster, longer stride costs more power
    fast = p.simulate(_slow_walk(step_length=0.09, period=0.4), record=False)["quality"]
    assert fast["mean_power_w"] > q["mean_power_w"]


def test_quality_agrees_across_backends():
    p = make_gait_problem("nao", backend="native", horizon=1.5)
    x = jnp.asarray([_slow_walk()], jnp.float32)
    runs = {b: jax.jit(lambda x, b=b: p.replace(backend=b).metrics(x, quality=True))(x)
            for b in ("native", "mjx")}
    n, m = runs["native"], runs["mjx"]
    for k in ("energy_j", "mean_power_w", "peak_power_w", "cost_of_transport", "foot_slip_m"):
        np.testing.assert_allclose(np.asarray(m[k]), np.asarray(n[k]), rtol=0.02, err_msg=k)
    for k in ("peak_speed_frac", "peak_torque_frac", "airborne_fraction", "min_foot_gap_m"):
        np.testing.assert_allclose(np.asarray(m[k]), np.asarray(n[k]), atol=0.02, err_msg=k)
    np.testing.assert_allclose(np.asarray(m["rms_torque_frac"]),
                               np.asarray(n["rms_torque_frac"]), atol=0.02)


def test_energy_penalty_lowers_fitness():
    x = jnp.asarray([_slow_walk()], jnp.float32)
    plain = make_gait_problem("nao", backend="native", horizon=2.0)
    cot = plain.replace(penalty="cot", penalty_weight=0.1)
    power = plain.replace(penalty="power", penalty_weight=0.001)
    f0 = float(plain.metrics(x)["fitness"][0])
    q = plain.metrics(x, quality=True)
    f_cot = float(cot.metrics(x)["fitness"][0])
    expected = f0 - 0.1 * float(q["energy_j"][0]) / (5.2473 * 9.81)
    assert f_cot == pytest.approx(expected, rel=1e-3) and f_cot < f0
    f_pow = float(power.metrics(x)["fitness"][0])
    assert f_pow == pytest.approx(f0 - 0.001 * float(q["mean_power_w"][0]), rel=1e-4)
    with pytest.raises(ProblemError, match="penalty"):
        make_gait_problem("nao", backend="native", penalty="speed")
    with pytest.raises(ProblemError, match="motor datasheet"):
        make_gait_problem("ant", backend="native", penalty="cot")
