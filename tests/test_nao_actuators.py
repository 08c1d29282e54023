"""NAO V5 actuation: the compiled model carries the datasheet's motor constants, a joint commanded
far away stays inside the DC motor's torque-speed envelope on both backends, the coupled
HipYawPitch pair moves as one, and MJX agrees with native MuJoCo on a walking trajectory.

Envelope checks use the datasheet values (``spec.stall_torque``, ``spec.no_load_speed``), not the
model's, so a wrong forcerange or damping in ``nao.xml`` fails them. The torque applied to a joint
during a step is ``actuator_force - damping * qvel_next`` (implicitfast integrates the damping
with the end-of-step velocity), compared with ``stall * (1 - |qvel| / w0)`` when it drives.

MJX-vs-native tolerance: the same equations in float32 (MJX) and float64 (C); contact onsets
amplify rounding, so a stable walking gait's torso stays within 5 mm after 3 s (measured 2 mm)
and within 5 cm after 20 s (measured 1.7 cm), with the same fall outcome.
"""

import json

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.robot import ROBOTS_DIR, load_model, load_robot, motor_constants
from eaco_jax.problems.gait import make_gait_problem

STEPS = 100  # 0.4 s at the fast timestep
FAR = {  # joint -> commanded target (far end of its range)
    "HeadYaw": 2.0, "LShoulderPitch": -2.0, "RShoulderRoll": -1.3,
    "LHipYawPitch": -1.1, "RHipYawPitch": -1.1, "LHipRoll": 0.75, "LHipPitch": 0.45,
    "LKneePitch": -0.05, "RAnklePitch": 0.9, "RAnkleRoll": 0.35,
}


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def _floating(nao):
    """The NAO 1 m above the floor with gravity off: only the motors and inertia act."""
    model = load_model(nao)
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    qpos = np.zeros(model.nq)
    qpos[:7] = [0, 0, 1.0, 1, 0, 0, 0]
    ctrl = np.asarray(nao.stand_ctrl, np.float64).copy()
    for i, name in enumerate(nao.joint_names):
        qpos[model.joint(name).qposadr[0]] = ctrl[i]
    for name, target in FAR.items():
        ctrl[nao.joint_names.index(name)] = target
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return model, data, ctrl


def _dofs(model, nao):
    return np.array([model.joint(n).dofadr[0] for n in nao.joint_names])


def _check_envelope(nao, model, force, qvel_next):
    """force (steps, nu), qvel_next (steps, nu) against the datasheet envelope (nao.xml rounds
    its constants to 4 digits: 1e-3 relative slack)."""
    stall = np.asarray(nao.stall_torque)
    w0 = np.asarray(nao.no_load_speed)
    assert np.all(np.abs(force) <= stall * (1 + 1e-3)), "actuator force above stall torque"
    tau = force - model.dof_damping[_dofs(model, nao)] * qvel_next
    # the coupled HipYawPitch pair is one motor: add its halves (their speeds are equal)
    li, ri = nao.joint_names.index("LHipYawPitch"), nao.joint_names.index("RHipYawPitch")
    np.testing.assert_allclose(qvel_next[:, li], qvel_next[:, ri], atol=0.05 * w0[li])
    tau[:, li] += tau[:, ri]
    stall = stall.copy()
    stall[li] *= 2
    keep = np.arange(nao.nu) != ri
    tau, w, stall, w0 = tau[:, keep], qvel_next[:, keep], stall[keep], w0[keep]
    driving = tau * w > 0
    limit = stall * (1 - np.abs(w) / w0)
    excess = np.where(driving, np.abs(tau) - limit, -np.inf)
    assert excess.max() <= 1e-3 * stall.max(), f"above the torque-speed line by {excess.max()}"
    # driving implies |w| < w0; a load may still back-drive a joint faster (as on a real motor)
    names = [n for n in nao.joint_names if n != "RHipYawPitch"]
    far = [n for n in FAR if n in names]
    idx = [names.index(n) for n in far]
    peak = np.abs(w[:, idx]).max(0) / w0[idx]
    assert np.all(peak >= 0.8), f"far from no-load speed: {dict(zip(far, peak, strict=True))}"


def test_model_constants_match_datasheet(nao):
    model = load_model(nao)
    raw = json.loads((ROBOTS_DIR / "nao.json").read_text())
    mc = motor_constants(raw, list(nao.joint_names))
    dofs = _dofs(model, nao)
    np.testing.assert_allclose(model.actuator_forcerange[:, 1], mc["stall"], rtol=1e-3)
    np.testing.assert_allclose(model.actuator_forcerange[:, 0], -np.asarray(mc["stall"]), rtol=1e-3)
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], mc["kp"], rtol=1e-3)
    np.testing.assert_allclose(-model.actuator_biasprm[:, 1], mc["kp"], rtol=1e-3)
    np.testing.assert_allclose(model.dof_damping[dofs], mc["damping"], rtol=1e-3)
    np.testing.assert_allclose(model.dof_armature[dofs], mc["armature"], rtol=1e-3)
    assert np.all(model.dof_frictionloss == 0)  # lumped into the damping (see nao.xml)
    # the numbers: pitch legs 68 mN m x 130.85, roll legs x 201.3 (8300 rpm motor)
    by = dict(zip(nao.joint_names, zip(nao.stall_torque, nao.no_load_speed, strict=True),
                  strict=True))
    assert by["LKneePitch"] == pytest.approx((8.90, 6.64), abs=0.01)
    assert by["LHipRoll"] == pytest.approx((13.69, 4.32), abs=0.01)
    assert by["LHipYawPitch"][0] == pytest.approx(13.69 / 2, abs=0.01)  # half of one motor
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.neq == 1 and model.eq_type[0] == mujoco.mjtEq.mjEQ_JOINT
    assert sum(model.body_mass) == pytest.approx(5.25, abs=0.01)  # NAO V4/V5 link masses


def test_envelope_native(nao):
    model, data, ctrl = _floating(nao)
    data.ctrl[:] = ctrl
    dofs = _dofs(model, nao)
    force, qvel = [], []
    for _ in range(STEPS):
        mujoco.mj_step(model, data)
        force.append(data.actuator_force.copy())
        qvel.append(data.qvel[dofs].copy())
    _check_envelope(nao, model, np.array(force), np.array(qvel))


def test_envelope_mjx(nao):
    from mujoco import mjx

    model, data, ctrl = _floating(nao)
    mm = mjx.put_model(model)
    assert mm.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # damping implicit
    d = mjx.make_data(mm).replace(qpos=jnp.asarray(data.qpos, jnp.float32),
                                  ctrl=jnp.asarray(ctrl, jnp.float32))
    dofs = jnp.asarray(_dofs(model, nao))

    def body(d, _):
        d = mjx.step(mm, d)
        return d, (d.actuator_force, d.qvel[dofs])

    _, (force, qvel) = jax.jit(lambda d: jax.lax.scan(body, d, None, length=STEPS))(d)
    _check_envelope(nao, model, np.asarray(force, np.float64), np.asarray(qvel, np.float64))


@pytest.mark.parametrize("damped", [True, False])
def test_knee_alone_runs_at_no_load_speed(nao, damped):
    """One joint driven alone, others holding: it approaches w0 and stays under it; without the
    back-EMF damping the same command overspeeds (so the envelope checks can fail)."""
    model, data, far = _floating(nao)
    knee = nao.joint_names.index("LKneePitch")
    ctrl = np.asarray(nao.stand_ctrl, np.float64).copy()
    ctrl[knee] = far[knee]
    if not damped:
        model.dof_damping[:] = 0.0
    data.ctrl[:] = ctrl
    dof = model.joint("LKneePitch").dofadr[0]
    peak = 0.0
    for _ in range(STEPS):
        mujoco.mj_step(model, data)
        peak = max(peak, abs(data.qvel[dof]))
    w0 = nao.no_load_speed[knee]
    if damped:
        assert 0.9 * w0 < peak <= w0
    else:
        assert peak > 1.5 * w0


def _slow_walk():
    g = dict(step_length=0.06, hip_height=0.21, duty_ratio=0.6, period=0.5, foot_lift=0.02,
             step_width=0.01, lateral_sway=0.02, torso_pitch=0.05, arm_swing=0.3,
             hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
             turn_rate=0.0)
    return [g[n] for n in we.PARAM_NAMES]


def _agree(horizon, torso_tol, distance_tol):
    p = make_gait_problem("nao", backend="native", horizon=horizon)
    runs = {b: p.simulate(_slow_walk(), record=True, backend=b) for b in ("native", "mjx")}
    n, m = runs["native"], runs["mjx"]
    assert not n["fell"] and not m["fell"]
    assert n["distance_m"] > 0.12 * horizon  # it walks (about 0.19 m/s)
    gap = np.linalg.norm(n["torso_xyz"] - m["torso_xyz"], axis=1)
    assert gap.max() < torso_tol, f"torso paths part by {gap.max():.4f} m"
    assert abs(n["distance_m"] - m["distance_m"]) < distance_tol
    li, ri = (n["joints"][k] for k in ("LHipYawPitch", "RHipYawPitch"))
    np.testing.assert_allclose(li, ri, atol=5e-3)  # one motor, one angle (soft constraint)


def test_backends_agree_walking_3s():
    _agree(3.0, torso_tol=0.005, distance_tol=0.005)


@pytest.mark.slow
def test_backends_agree_walking_20s():
    _agree(20.0, torso_tol=0.05, distance_tol=0.03)


def test_turning_through_the_shared_hip_yaw_motor(nao):
    """The walk engine commands both HipYawPitch joints alike (one motor) and still turns: the
    torso's heading follows the sign of turn_rate."""
    p = make_gait_problem("nao", backend="native", horizon=3.0)
    heading = {}
    for rate in (-0.3, 0.3):
        g = _slow_walk()
        g[we.PARAM_NAMES.index("turn_rate")] = rate
        g[we.PARAM_NAMES.index("step_length")] = 0.04
        sim = p.simulate(g, record=True)
        np.testing.assert_array_equal(sim["controls"][:, nao.joint_names.index("LHipYawPitch")],
                                      sim["controls"][:, nao.joint_names.index("RHipYawPitch")])
        w, x, y, z = sim["qpos"][-1, 3:7]
        heading[rate] = np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
        assert not sim["fell"]
    assert heading[0.3] > 15.0 and heading[-0.3] < -15.0
