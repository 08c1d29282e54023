"""The motor limits in the physics (nao.json ``motors.limits_in_physics``): the current limit
caps the joint torque driving and braking, the gear efficiency divides the torque-speed line
while driving, the direct-torque model applies exactly the computed torque, and the rollouts
keep every motor current within its limit on both backends.

Hand numbers (NAO knee, type-1 motor through 130.85:1): stall 0.068 x 130.85 = 8.898 N m,
no-load speed 8300 rpm / 130.85 = 6.643 rad/s, k_b = stall / no-load speed, gear efficiency
0.75, current limit = the stall current, so the driving cap at rest is 0.75 x 8.898 N m and
the braking cap 8.898 / 0.75 N m.
"""

import copy
import json
import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_native import native_model, native_rollout, nominal_motor, torque_model
from eaco_jax.gait.worlds import couple_controls
from eaco_jax.problems.gait import make_gait_problem

STALL = 0.068 * 130.85
W0 = 8300 * 2 * math.pi / 60 / 130.85
KB = STALL / W0
ETA = 0.75


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def _knee(nao):
    return nao.joint_names.index("LKneePitch")


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_limited_torque_hand_cases(nao, xp):
    mm = mo.motor_model(nao)
    j = _knee(nao)
    one = mo.MotorModel(*(np.asarray(f)[j : j + 1] for f in mm))
    # (servo, qdot) -> expected joint torque
    cases = [
        (STALL, 0.0, ETA * STALL),  # blocked joint, saturated servo: the driving cap
        (1.0, 0.0, 1.0),  # below every cap: the servo's torque
        (STALL, 2.0, ETA * (STALL - KB * 2.0)),  # driving at 2 rad/s: eta x the voltage line
        (-STALL, -2.0, -ETA * (STALL - KB * 2.0)),  # the same, the other way
        (-STALL, 4.0, -STALL / ETA),  # braking at 4 rad/s: stall + k_b 4 > the braking cap
        (-STALL, 1.0, -(STALL + KB * 1.0)),  # braking at 1 rad/s: within the braking cap
        (STALL, 2.0 * W0, -STALL),  # overrun at 2 w0: back-EMF brakes, within the braking cap
        (-STALL, W0, -STALL / ETA),  # braking at w0 against the servo (2 x stall): capped
    ]
    servo = xp.asarray([[c[0]] for c in cases], xp.float32)
    qdot = xp.asarray([[c[1]] for c in cases], xp.float32)
    stall = xp.full_like(servo, STALL)
    speed = xp.full_like(servo, W0)
    got = np.asarray(mo.limited_torque(servo, qdot, stall, speed, one, xp))[:, 0]
    np.testing.assert_allclose(got, [c[2] for c in cases], rtol=2e-5)


def test_current_at_the_cap_is_the_limit(nao):
    """At the driving cap at rest and at the braking cap the motor draws its limit current."""
    mm = mo.motor_model(nao)
    j = _knee(nao)
    tau = np.zeros((2, nao.nu))
    qdot = np.zeros((2, nao.nu))
    tau[0, j], qdot[0, j] = ETA * STALL, 0.0
    tau[1, j], qdot[1, j] = -STALL / ETA, 3.0
    i = mo.current(tau, qdot, mm, np)[:, j]
    np.testing.assert_allclose(np.abs(i), mm.i_limit[j], rtol=1e-3)


def test_knee_driven_alone_follows_the_driving_cap(nao):
    """The direct-torque model, gravity off, the knee commanded to its far end: the actuator
    force MuJoCo applies is the computed torque; while the servo is saturated it is
    0.75 x (stall - k_b w), and the knee runs up towards the speed where that equals the
    friction drag, 0.75 w0 / (0.75 + 0.02) (the 2 % friction loss stays as joint damping)."""
    model = copy.copy(torque_model(nao, 0.0, "fast"))  # a copy: the cached one stays as is
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    qadr = np.array([model.joint(n).qposadr[0] for n in nao.joint_names])
    dofs = np.array([model.joint(n).dofadr[0] for n in nao.joint_names])
    data.qpos[:7] = [0, 0, 1.0, 1, 0, 0, 0]
    data.qpos[qadr] = nao.stand_ctrl
    ctrl = np.asarray(nao.stand_ctrl, np.float64).copy()
    j = _knee(nao)
    ctrl[j] = 2.1
    mujoco.mj_forward(model, data)
    mp = ql.MotorParams(*(np.asarray(a, np.float64) for a in
                          nominal_motor(nao, native_model(nao, 0.0, "fast"))))
    mm = mo.motor_model(nao)
    speeds, forces, taus = [], [], []
    for _ in range(150):
        q, qdot = data.qpos[qadr].copy(), data.qvel[dofs].copy()
        tau = ql.motor_torque(q, qdot, ctrl, mp, mm, np)
        data.ctrl[:] = tau
        mujoco.mj_step(model, data)
        speeds.append(qdot[j] if mp.kp[j] * (ctrl[j] - q[j]) >= STALL else -1.0)
        taus.append(tau[j])
        forces.append(data.actuator_force[j])
    speeds, forces, taus = map(np.asarray, (speeds, forces, taus))
    np.testing.assert_allclose(forces, taus, rtol=1e-9, atol=1e-9)  # no clamp in the model
    moving = speeds > 0.5  # saturated and driving
    assert moving.sum() > 30
    # rtol: nao.xml writes the stall torque to 4 digits
    np.testing.assert_allclose(taus[moving], ETA * (STALL - KB * speeds[moving]), rtol=1e-4)
    w_end = ETA * W0 / (ETA + 0.02)
    # settles there; the explicit back-EMF (time step 4 ms ~ the motor's mechanical time
    # constant) overshoots it by about 1 % on the way
    assert speeds[moving][-1] == pytest.approx(w_end, rel=0.005)
    assert speeds.max() <= w_end * 1.02


def _stored_controls(nao, horizon):
    best = json.loads(open("experiments/results/nao_best_gait.json").read())
    p = make_gait_problem(nao, backend="native", horizon=horizon)
    return np.asarray(p.controls(jnp.asarray([best["vector"]], jnp.float32)))


def test_native_currents_stay_within_the_limit(nao):
    """The stored gait, 2 s: with the limits in the physics no motor current exceeds its
    limit; without them the same gait brakes above it (so the check can fail)."""
    assert mo.physics_limits(nao)
    ctrl = couple_controls(_stored_controls(nao, 2.0), nao, xp=np)
    mm = mo.motor_model(nao)
    peak = {lim: np.max(native_rollout(ctrl, nao, quality=True, limits=lim)["acc"]["peak_i"][0]
                        / mm.i_limit) for lim in (True, False)}
    assert peak[True] <= 1.0 + 1e-5
    assert peak[False] > 1.2


@pytest.mark.slow  # compiles MJX's step
def test_mjx_agrees_with_native_under_the_limits(nao):
    from eaco_jax.gait.rollout_mjx import mjx_rollout

    c = _stored_controls(nao, 2.0)
    m = jax.jit(lambda c: mjx_rollout(c, nao, quality=True))(c)
    n = native_rollout(couple_controls(c, nao, xp=np), nao, quality=True)
    np.testing.assert_allclose(np.asarray(m["trace"])[..., :3], n["trace"][..., :3], atol=1e-3)
    mm = mo.motor_model(nao)
    assert np.max(np.asarray(m["acc"]["peak_i"]) / mm.i_limit) <= 1.0 + 1e-5
    np.testing.assert_allclose(np.asarray(m["acc"]["loss_j"]), n["acc"]["loss_j"], rtol=0.02,
                               atol=1e-3)
