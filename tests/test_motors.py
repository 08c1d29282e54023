"""Motor model (eaco_jax.gait.motors): hand-computed current, losses and electrical power,
driving vs braking efficiency, the current cap, the two-node thermal model against its exact
solution (matrix exponential), steady state, endurance for a constant loss, the NAO constants
derived from nao.json, and the same electrical/thermal metrics on numpy and JAX and on both
rollout backends."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.robot import load_robot
from eaco_jax.problems.gait import make_gait_problem

# one joint: ratio 100, k_t 0.02 N m/A -> 2 N m/A at the joint; R 5 ohm; eta 0.8; limit 2 A
MM = mo.MotorModel(*(np.array([v], np.float64) for v in (
    100.0, 1.0, 0.02, 5.0, 0.5, 2.0, 0.8, 4.0, 12.0, 10.0, 400.0, 75.0, 25.0, 100.0)))


def _a(*v):
    return np.array(v, np.float64)[:, None]


def test_constant_torque_current_losses_and_power():
    tau, qdot = _a(1.6, 1.6, 4.0), _a(2.0, -2.0, -0.5)
    i = mo.current(tau, qdot, MM, np)
    # driving: 1.6 / 2 / 0.8 = 1 A; braking: 1.6 * 0.8 / 2 = 0.64 A; 4 * 0.8 / 2 = 1.6 A
    np.testing.assert_allclose(i[:, 0], [1.0, 0.64, 1.6])
    np.testing.assert_allclose(mo.copper_loss(i, MM, np)[:, 0], [5.0, 2.048, 12.8])
    # electrical: loss + shaft (3.2 / 0.8 driving; -3.2 * 0.8, -2 * 0.8 braking), never < 0
    np.testing.assert_allclose(mo.electrical_power(tau, qdot, i, MM, np)[:, 0],
                               [5.0 + 4.0, 0.0, 12.8 - 1.6])


def test_current_cap_driving_and_braking():
    tau = _a(10.0, 10.0, -10.0, 1.0)
    qdot = _a(1.0, -1.0, 1.0, -1.0)
    # driving cap 2 A * 2 N m/A * 0.8 = 3.2; braking cap 2 * 2 / 0.8 = 5
    np.testing.assert_allclose(mo.torque_cap(tau, qdot, MM, np)[:, 0], [3.2, 5.0, -5.0, 1.0])


def _ab():
    """The two-node model of MM written out by hand: C_w = tau_w / R_wh = 10 / 4 J/K,
    C_h = tau_h / R_ha = 400 / 12 J/K."""
    c_w, c_h, r1, r2 = 10.0 / 4.0, 400.0 / 12.0, 4.0, 12.0
    a = np.array([[-1 / (r1 * c_w), 1 / (r1 * c_w)],
                  [1 / (r1 * c_h), -(1 / r1 + 1 / r2) / c_h]])
    return a, np.array([1 / c_w, 0.0])


def _exact(t, power):
    """Winding and housing above ambient at time t for a constant loss (matrix exponential of
    the augmented system, independent of the module's modal form)."""
    a, b = _ab()
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[:2, 2] = a, b * power
    return (expm(aug * t) @ np.array([0.0, 0.0, 1.0]))[:2]


def test_thermal_step_response_matches_exact_solution():
    power, dt = 3.0, 0.02
    md = mo.modes(MM, dt)
    z = np.zeros((1, 1, 2))
    t = 0.0
    for n in (1, 50, 500, 3000):  # control steps
        z = mo.advance(z, np.full((1, n, 1), power), md, np)
        t += n * dt
        ref = _exact(t, power)
        np.testing.assert_allclose(mo.temperatures(z, md, np)[0, 0], ref, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(mo.step_response(t, np.array([power]), MM, np)[0], ref,
                                   rtol=1e-9)


def test_thermal_varying_loss_is_exact_per_control_step():
    dt, losses = 0.02, np.array([4.0, 0.0, 9.0, 1.0])
    md = mo.modes(MM, dt)
    z = mo.advance(np.zeros((1, 1, 2)), losses[None, :, None], md, np)
    a, b = _ab()
    x = np.zeros(2)
    for p in losses:  # exact zero-order hold, step by step
        aug = np.zeros((3, 3))
        aug[:2, :2], aug[:2, 2] = a, b * p
        x = (expm(aug * dt) @ np.append(x, 1.0))[:2]
    np.testing.assert_allclose(mo.temperatures(z, md, np)[0, 0], x, rtol=1e-9)


def test_steady_state_is_ambient_plus_p_times_resistances():
    power = np.array([2.5])
    ss = mo.steady_state(power, MM, np)[0]
    np.testing.assert_allclose(ss, [2.5 * (4.0 + 12.0), 2.5 * 12.0])
    np.testing.assert_allclose(_exact(1e5, 2.5), ss, rtol=1e-9)


def test_endurance_for_a_constant_loss_matches_closed_form():
    power = np.array([4.0])  # steady winding 64 K above ambient > the 50 K to the limit
    t_ref = brentq(lambda t: _exact(t, 4.0)[0] - 50.0, 1e-6, 1e5, xtol=1e-9)
    got = mo.minutes_to_limit(power, np.zeros(1), MM, np)[0]
    assert got == pytest.approx(t_ref / 60.0, rel=1e-6)
    # a ripple bound of 5 K moves the crossing to where the mean response reaches 45 K
    t5 = brentq(lambda t: _exact(t, 4.0)[0] - 45.0, 1e-6, 1e5, xtol=1e-9)
    assert mo.minutes_to_limit(power, np.array([5.0]), MM, np)[0] == pytest.approx(t5 / 60.0,
                                                                                  rel=1e-6)
    assert np.isinf(mo.minutes_to_limit(np.array([3.0]), np.zeros(1), MM, np)[0])  # 48 K < 50


def test_ripple_bound_on_blocks():
    seconds = np.array([4.0])
    # 4 blocks of 1 s: all the loss (8 J) in the first block, mean 2 W: the cumulative loss
    # runs up to 8 J within the first second while 2 t is at most 2 -> M <= 8 (at t = 1: 6)
    blocks = np.array([[[8.0], [0.0], [0.0], [0.0]]])
    r = mo.ripple_bound(blocks, seconds, np.array([[2.0]]), MM, np)
    c_w = 10.0 / 4.0
    assert r[0, 0] == pytest.approx(2 * 8.0 / c_w)
    even = mo.ripple_bound(np.full((1, 4, 1), 2.0), seconds, np.array([[2.0]]), MM, np)
    assert even[0, 0] == pytest.approx(2 * 2.0 / c_w)  # only the within-block slack


def test_nao_constants_from_spec():
    mm = mo.motor_model(load_robot("nao"))
    j = load_robot("nao").joint_names.index("LKneePitch")
    w0 = 8300 * 2 * np.pi / 60
    assert mm.k_t[j] == pytest.approx(21.6 / w0)
    assert mm.r_ohm[j] == pytest.approx(21.6 * (21.6 / w0) / 0.068)
    assert mm.i_cont[j] * mm.k_t[j] == pytest.approx(0.0161)
    # the continuous current heats the winding to its maximum (100 C) at 25 C
    loss = mm.i_cont[j] ** 2 * mm.r_ohm[j]
    assert 25.0 + loss * (mm.rth_wh[j] + mm.rth_ha[j]) == pytest.approx(100.0)
    hyp = load_robot("nao").joint_names.index("LHipYawPitch")
    assert mm.share[hyp] == 0.5 and mm.share[j] == 1.0


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_electrical_accumulators_on_a_constructed_case(xp):
    mp = ql.MotorParams(kp=np.array([1e4]), stall=np.array([1.6]), damping=np.array([0.0]),
                        no_load_speed=np.array([10.0]), nominal=np.array([1.0]),
                        ctrl_lo=np.array([-1.0]), ctrl_hi=np.array([1.0]))
    el = ql.Electrics(MM, mo.modes(MM, 0.02), substeps=2, horizon=4)
    # saturated drive: tau = 1.6 driving at +2 rad/s -> 1 A, 5 W loss, 9 W electrical
    q = np.zeros((1, 4, 1), np.float32)
    qdot = np.full((1, 4, 1), 2.0, np.float32)
    ctrl = np.ones((1, 1, 1), np.float32)
    alive = np.array([[True, True, True, True]])
    acc = ql.new_acc((1,), 1, xp, motor=True)
    acc = ql.add_physics(acc, *(xp.asarray(a) for a in (q, qdot, ctrl, alive)), mp, 0.01, xp,
                         el=el, step0=0)
    assert float(acc["energy_el"][0]) == pytest.approx(4 * 9.0 * 0.01, rel=1e-6)
    assert float(acc["loss_j"][0, 0]) == pytest.approx(4 * 5.0 * 0.01, rel=1e-6)
    np.testing.assert_allclose(np.asarray(acc["loss_blocks"][0, :, 0]).sum(), 0.2, rtol=1e-6)
    assert float(np.asarray(acc["loss_blocks"][0, 0, 0])) == pytest.approx(0.1, rel=1e-6)
    temps = mo.temperatures(np.asarray(acc["therm"], np.float64), el.modes, np)[0, 0]
    np.testing.assert_allclose(temps, _exact(0.04, 5.0), rtol=1e-5)
    out = ql.finalize(jax.tree.map(jnp.asarray, acc), jnp.array([0.1]), 5.0, 0.01,
                      jnp.asarray(mp.nominal), MM)
    assert float(out["rms_current_frac"][0, 0]) == pytest.approx(1.0 / 0.5, rel=1e-6)
    assert float(out["peak_current_frac"][0, 0]) == pytest.approx(1.0 / 2.0, rel=1e-6)
    assert float(out["electrical_cot"][0]) == pytest.approx(0.36 / (5.0 * 9.81 * 0.1), rel=1e-5)
    assert float(out["winding_steady_c"][0, 0]) == pytest.approx(
        25.0 + 5.0 * 16.0 + float(out["winding_ripple_c"][0, 0]), rel=1e-5)


def _walk():
    v = dict(step_length=0.05, hip_height=0.21, duty_ratio=0.6, period=0.5, foot_lift=0.015,
             step_width=0.0, lateral_sway=0.01, torso_pitch=0.0, arm_swing=0.2,
             hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
             turn_rate=0.0)
    return [v[n] for n in we.PARAM_NAMES]


@pytest.mark.slow  # compiles MJX's step (about 1.5 min on 2 cores); numpy/JAX parity above
def test_motor_metrics_agree_across_backends():
    p = make_gait_problem("nao", backend="native", horizon=1.0)
    x = jnp.asarray([_walk()], jnp.float32)
    runs = {b: jax.jit(lambda x, b=b: p.replace(backend=b).metrics(x, quality=True))(x)
            for b in ("native", "mjx")}
    n, m = runs["native"], runs["mjx"]
    assert float(n["electrical_energy_j"][0]) > float(n["energy_j"][0]) > 0.0
    for k in ("electrical_energy_j", "electrical_cot", "copper_loss_w", "rms_current_frac"):
        np.testing.assert_allclose(np.asarray(m[k]), np.asarray(n[k]), rtol=0.03, atol=1e-3,
                                   err_msg=k)
    for k in ("winding_end_c", "winding_10min_c", "winding_steady_c", "winding_ripple_c"):
        np.testing.assert_allclose(np.asarray(m[k]), np.asarray(n[k]), atol=0.5, err_msg=k)
    np.testing.assert_allclose(np.asarray(m["peak_current_frac"]),
                               np.asarray(n["peak_current_frac"]), atol=0.03)
