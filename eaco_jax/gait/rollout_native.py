"""Batched gait rollouts on MuJoCo's C engine, across all CPU threads (``mujoco.rollout``).

The controls are computed in JAX by the walk engine at the control rate, ``(B, T, nu)``, and
held for ``substeps`` physics steps each (or, where the spec says so,
:func:`eaco_jax.gait.motors.interpolates_targets`, moved linearly to the next one over them).
``mujoco.rollout`` runs the rollouts in parallel on a
persistent thread pool (one ``MjData`` per thread, one ``MjModel`` per rollout when the worlds
differ); to keep memory small the horizon is cut into time chunks (the state at the end of a chunk
starts the next; MuJoCo's solver warm start restarts at a chunk boundary, a chunk is at least
``STATE_BYTES_PER_CALL`` of states) and only the root pose after each control step is kept. The
result is the torso trace ``(B, T + 1, 7)`` (position, up axis, heading), row 0 the initial pose,
exactly what :func:`eaco_jax.gait.fitness.summarize` reads; with ``quality`` also the
accumulators of :mod:`eaco_jax.gait.quality`, computed from every physics step of each chunk.

With the motor limits in the physics (:func:`eaco_jax.gait.motors.physics_limits`, or
``limits=True``) the actuators are direct-torque ones (:func:`torque_model`) and each physics
step's torque is computed from that step's joint state
(:func:`eaco_jax.gait.quality.motor_torque`: current limit, torque-speed line, gear efficiency),
the same function MJX calls; ``mujoco.rollout`` then runs one physics step per call.

:func:`native_trace` is the plain host function (nominal world); :func:`native_rollout` the
general one (per-rollout models, initial poses and pushes); :func:`native_rollout_callback` wraps
it with ``jax.pure_callback`` so a jitted colony loop (``lax.scan`` in
:func:`eaco_jax.driver.minimize`) can call it, randomised worlds included; batching over seeds is
flattened into the rollout axis.
"""

from __future__ import annotations

import copy
import functools
import os
import re
import sys
import warnings

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait import steer as st
from eaco_jax.gait.fitness import is_down
from eaco_jax.gait.robot import RobotSpec, load_model, stand_qpos
from eaco_jax.gait.walk_engine import stand_pose
from eaco_jax.gait.worlds import (
    VARIED_FIELDS,
    Worlds,
    actuated_dofs,
    couple_controls,
    delayed_at,
    friction_geom_ids,
    initial_qpos,
    model_fields,
    push_at,
    world_ctrl_at,
)

TRACE_COLUMNS = 7
"""Torso trace columns: position (3), up axis (3), heading (yaw, rad)."""

STATE_BYTES_PER_CALL = 256 * 2**20
"""Upper bound of the state buffer one ``mujoco.rollout`` call may fill (sets the chunk)."""

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
_PUSH_SPEC = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED


class MujocoWarning(RuntimeWarning):
    """A warning of MuJoCo's C engine (e.g. "the simulation is unstable")."""


def mujoco_warning_kind(message: str) -> str:
    """``message`` without what varies between repeats (the DOF, the simulation time), so
    that Python's warning filter shows each kind once."""
    text = re.sub(r"\s*Time = \S+", "", message)
    return re.sub(r" at DOF \d+", "", text).strip()


def _mujoco_warning(message: str) -> None:
    # called by MuJoCo's C code, also from its rollout threads: must never raise (an
    # exception here aborts the process), so a warning filter set to "error" prints instead
    text = f"MuJoCo: {mujoco_warning_kind(message)}"
    try:
        warnings.warn(text, MujocoWarning, stacklevel=1)
    except BaseException:  # noqa: BLE001
        sys.stderr.write(f"warning: {text}\n")


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to Python's warnings (the terminal, once per kind) instead of
    its default: a ``MUJOCO_LOG.TXT`` in the working directory and a line on stdout. Leaves
    a handler the user has installed (``mujoco.set_mju_user_warning``) in place."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_mujoco_warning)


route_mujoco_warnings()


@functools.lru_cache(maxsize=16)
def native_model(spec: RobotSpec, slope_deg: float, accuracy: str) -> mujoco.MjModel:
    """The compiled model for ``(robot, slope, accuracy)``, cached."""
    return load_model(spec, slope_deg=slope_deg, accuracy=accuracy)


def to_torque_actuators(model: mujoco.MjModel, dofs, keep: float) -> mujoco.MjModel:
    """``model`` (changed in place) with direct-torque actuators: force = ctrl, no control or
    force clamp (the limits are applied when the command is computed), and only the friction
    share ``keep`` of the actuated ``dofs``' damping (the back-EMF is in the command)."""
    model.dof_damping[np.asarray(dofs)] *= keep
    model.actuator_gainprm[:] = 0.0
    model.actuator_gainprm[:, 0] = 1.0
    model.actuator_biasprm[:] = 0.0
    model.actuator_ctrllimited[:] = 0
    model.actuator_forcelimited[:] = 0
    return model


@functools.lru_cache(maxsize=16)
def torque_model(spec: RobotSpec, slope_deg: float, accuracy: str) -> mujoco.MjModel:
    """:func:`native_model` with direct-torque actuators (:func:`to_torque_actuators`)."""
    model = native_model(spec, slope_deg, accuracy)
    return to_torque_actuators(copy.copy(model), actuated_dofs(model, spec),
                               mo.friction_share(spec))


@functools.lru_cache(maxsize=16)
def _pool(nthread: int) -> mj_rollout.Rollout:
    return mj_rollout.Rollout(nthread=nthread)


def substeps(spec: RobotSpec, model: mujoco.MjModel) -> int:
    """Physics steps per control step (the control period must be a multiple of the timestep)."""
    n = spec.control_dt / model.opt.timestep
    if abs(n - round(n)) > 1e-6 or round(n) < 1:
        raise ValueError(
            f"control_dt {spec.control_dt} is not a multiple of timestep {model.opt.timestep}"
        )
    return int(round(n))


def initial_state(spec: RobotSpec, model: mujoco.MjModel, slope_deg: float,
                  qpos: np.ndarray | None = None) -> np.ndarray:
    """Full physics state of the standing keyframe (soles parallel to the inclined floor), or of
    the configuration ``qpos`` if given, at rest."""
    data = mujoco.MjData(model)
    if qpos is None:
        qpos = np.array(stand_qpos(spec, model))
        pose = stand_pose(spec, slope_deg)
        for name, value in zip(spec.joint_names, pose, strict=True):
            qpos[model.joint(name).qposadr[0]] = value
    data.qpos[:] = qpos
    data.ctrl[:] = stand_pose(spec, slope_deg)
    mujoco.mj_forward(model, data)
    state = np.empty(mujoco.mj_stateSize(model, _STATE))
    mujoco.mj_getState(model, data, state, _STATE)
    return state


def root_trace(qroot: np.ndarray) -> np.ndarray:
    """``(..., 7)`` root pose (xyz, wxyz) -> ``(..., 7)`` torso position, up (z) axis and
    heading (yaw of the torso's x axis, rad)."""
    w, x, y, z = (qroot[..., i] for i in range(3, 7))
    up = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.concatenate([qroot[..., :3], up, yaw[..., None]], -1).astype(np.float32)


def floor_normal(slope_deg: float) -> np.ndarray:
    """Unit normal of the floor plane (rising along +x by ``slope_deg``), through the origin."""
    a = np.radians(slope_deg)
    return np.array([-np.sin(a), 0.0, np.cos(a)], np.float32)


def _sole_adr(model: mujoco.MjModel, spec: RobotSpec) -> np.ndarray:
    return np.concatenate([model.sensor_adr[model.sensor(n).id] + np.arange(3)
                           for n in ql.sole_sensor_names(spec)])


def native_rollout(
    controls: np.ndarray,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    *,
    models: list[mujoco.MjModel] | None = None,
    qpos_init: np.ndarray | None = None,
    push: np.ndarray | None = None,
    quality: bool = False,
    motor: ql.MotorParams | None = None,
    record_qpos: bool = False,
    nthread: int | None = None,
    limits: bool | None = None,
    trace_every: int = 0,
    interpolate: bool | None = None,
    steer: st.SteerInputs | None = None,
    latency: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Roll out ``controls`` ``(B, T, nu)`` (one per control step) on the host.

    ``models`` one per rollout (default: the nominal model), ``qpos_init`` ``(B, nq)`` initial
    configurations at rest (default: the keyframe), ``push`` ``(B, T, 3)`` forces on the torso
    per control step. Returns ``trace`` ``(B, T + 1, 7)``, with ``record_qpos`` also ``qpos``
    ``(B, T + 1, nq)``, with ``quality`` the accumulators ``acc`` (``motor``: per-rollout
    :class:`~eaco_jax.gait.quality.MotorParams` ``(B, nu)``, default from the nominal model).
    ``limits`` (default: the spec's, :func:`~eaco_jax.gait.motors.physics_limits`): the motor
    limits in the physics; ``models`` are then position-servo models as without (their servo
    constants give ``motor``'s defaults) and are switched to direct torque here.
    ``steer`` (:mod:`eaco_jax.gait.steer`, its ``dcontrols`` ``(B, T, nu)`` delayed as
    ``controls``): the heading controller corrects the targets at every control
    step from the torso's pose; ``latency`` ``(B,)``: each rollout's latency (control steps,
    default 0), which delays the correction.
    """
    controls = np.asarray(controls, np.float64)
    if controls.ndim != 3 or controls.shape[-1] != spec.nu:
        raise ValueError(f"controls must be (B, T, {spec.nu}), got {controls.shape}")
    base = native_model(spec, float(slope_deg), accuracy)
    k = substeps(spec, base)
    nb, steps, _ = controls.shape
    limits = mo.physics_limits(spec) if limits is None else bool(limits)
    if limits and mo.motor_model(spec) is None:
        raise ValueError(f"robot {spec.name}: no electrical motor data, no limits to apply")
    interpolate = mo.interpolates_targets(spec) if interpolate is None else bool(interpolate)
    model_arg = base if models is None else list(models)
    if limits:
        motor = motor or nominal_motor(spec, base)
        model_arg = (torque_model(spec, float(slope_deg), accuracy) if models is None else
                     _torque_copies(model_arg, spec))
    nthread = nthread or os.cpu_count() or 1
    datas = [mujoco.MjData(base) for _ in range(nthread)]
    if qpos_init is None:
        state = np.tile(initial_state(spec, base, slope_deg), (nb, 1))
    else:
        state = np.stack([initial_state(spec, model_arg[i] if models else base, slope_deg,
                                        qpos_init[i]) for i in range(nb)])
    nstate = state.shape[1]
    per_ctrl = max(1, STATE_BYTES_PER_CALL // (8 * nstate * k * max(nb, 1)))
    if steer is not None:  # the controller acts between control steps: one step per chunk
        per_ctrl = 1
        dctrl = np.asarray(steer.dcontrols, np.float64)
        if dctrl.shape != controls.shape:
            raise ValueError(f"steer.dcontrols must be {controls.shape}, got {dctrl.shape}")
        lat = np.zeros(nb, np.int64) if latency is None else np.asarray(latency).reshape(nb)
        rates = None
        if steer.steering.track_turn:
            if steer.rates is None or np.size(steer.rates) != nb:
                raise ValueError(f"steering.track_turn needs steer.rates, one per rollout ({nb})")
            rates = np.asarray(steer.rates, np.float64).reshape(nb)
        sstate = st.start_state(nb, np)
        u_prev_end = controls[:, 0]
    trace = np.empty((nb, steps + 1, TRACE_COLUMNS), np.float32)
    trace[:, 0] = root_trace(state[:, 1:8])
    qpos_rec = np.empty((nb, steps + 1, base.nq), np.float32) if record_qpos else None
    if record_qpos:
        qpos_rec[:, 0] = state[:, 1 : 1 + base.nq]
    acc = None
    dofs = np.asarray(actuated_dofs(base, spec))
    qadr = np.array([base.joint(n).qposadr[0] for n in spec.joint_names])
    feedback = None
    if limits:
        feedback = _Feedback(motor, nb, spec.nu, mo.motor_model(spec), qadr, dofs, model_arg,
                             state)
    if quality:
        el = ql.electrics(spec, spec.control_dt, k, steps, trace_every)
        acc = ql.new_acc((nb,), spec.nu, xp=np, motor=el is not None,
                         trace_samples=ql.trace_samples(el))
        motor = motor or nominal_motor(spec, base)
        mp = ql.MotorParams(*(np.broadcast_to(np.asarray(a, np.float32), (nb, spec.nu))[:, None]
                              for a in motor))
        sole = _sole_adr(base, spec)
        normal = floor_normal(slope_deg)
        radius = float(base.geom_size[base.geom(spec.foot_geoms[0]).id, 0])
        alive = ~is_down(trace[:, 0, :3], trace[:, 0, 3:6], spec.fall_height, spec.fall_tilt_deg,
                         slope_deg, xp=np)
    pool = _pool(nthread)
    for start in range(0, steps, per_ctrl):
        stop = min(steps, start + per_ctrl)
        if steer is None:
            ctrl = physics_controls(controls, start, stop, k, interpolate)
        else:
            c_old = sstate.c_prev
            ref = None if rates is None else st.turn_reference(rates, start, spec.control_dt)
            sstate, c = st.update(sstate, root_trace(state[:, 1:8]), trace[:, 0, :2],
                                  steer.direction, steer.steering, spec.control_dt, np, ref)
            c_eff = st.delayed(c, c_old, lat)[:, None].astype(np.float64)
            if interpolate:
                tn = min(start + 1, steps - 1)
                u, u_next = u_prev_end, controls[:, tn] + c_eff * dctrl[:, tn]
            else:
                u = u_next = controls[:, start] + c_eff * dctrl[:, start]
            u_prev_end = u_next
            ctrl = np.ascontiguousarray(
                mo.physics_targets(u, u_next, k, interpolate, np).reshape(nb, k, -1))
        spec_bits = mujoco.mjtState.mjSTATE_CTRL
        if push is not None:
            qfrc = np.zeros(ctrl.shape[:2] + (base.nv,))
            qfrc[..., :3] = np.repeat(np.asarray(push[:, start:stop], np.float64), k, axis=1)
            ctrl = np.concatenate([ctrl, qfrc], axis=-1)
            spec_bits = _PUSH_SPEC
        taus = None
        if feedback is None:
            out, sens = pool.rollout(model_arg, datas, state, ctrl,
                                     control_spec=int(spec_bits))
        else:
            out, sens, taus, speeds = feedback.run(ctrl)
        sampled = out[:, k - 1 :: k]  # state after each control step
        rows = root_trace(sampled[..., 1:8])
        trace[:, start + 1 : stop + 1] = rows
        if record_qpos:
            qpos_rec[:, start + 1 : stop + 1] = sampled[..., 1 : 1 + base.nq]
        if quality:
            down = is_down(rows[..., :3], rows[..., 3:6], spec.fall_height, spec.fall_tilt_deg,
                           slope_deg, xp=np)
            # alive during control step t: samples 0..t upright
            alive_k = alive[:, None] & np.concatenate(
                [np.ones((nb, 1), bool), np.cumprod(~down[:, :-1], axis=1).astype(bool)], 1)
            q_before = np.concatenate([state[:, None, 1 : 1 + base.nq], out[:, :-1, 1:1 + base.nq]],
                                      axis=1)[..., qadr]
            # with the limits in the physics, the speeds each torque was computed at
            qdot = out[..., 1 + base.nq + dofs] if taus is None else speeds
            acc = ql.add_physics(acc, q_before.astype(np.float32), qdot.astype(np.float32),
                                 ctrl[..., : spec.nu].astype(np.float32),
                                 np.repeat(alive_k, k, axis=1), mp, float(base.opt.timestep),
                                 xp=np, el=el, step0=start,
                                 tau=None if taus is None else taus.astype(np.float32))
            soles = sens[:, k - 1 :: k][..., sole].reshape(nb, stop - start, -1, 3)
            acc = ql.add_control(acc, soles.astype(np.float32), alive_k, normal, radius, xp=np)
            alive = alive & ~np.any(down, axis=1)
        state = np.ascontiguousarray(out[:, -1])
    result: dict[str, np.ndarray] = {"trace": trace}
    if record_qpos:
        result["qpos"] = qpos_rec
    if quality:
        result["acc"] = {k_: np.asarray(v, np.float32) if v.dtype.kind == "f" else v
                         for k_, v in acc.items()}
    return result


def physics_controls(controls: np.ndarray, start: int, stop: int, k: int,
                     interpolate: bool) -> np.ndarray:
    """Targets ``(B, (stop - start) k, nu)`` of the physics steps of control steps
    ``start .. stop - 1`` of ``controls`` ``(B, T, nu)``: held, or moving linearly toward the
    next control step's (:func:`~eaco_jax.gait.motors.physics_targets`; the last is held)."""
    if not interpolate:
        return np.repeat(controls[:, start:stop], k, axis=1)
    nxt = controls[:, np.minimum(np.arange(start + 1, stop + 1), controls.shape[1] - 1)]
    ctrl = mo.physics_targets(controls[:, start:stop], nxt, k, True, np)
    return ctrl.reshape(ctrl.shape[0], -1, ctrl.shape[-1])


def _torque_copies(models: list[mujoco.MjModel], spec: RobotSpec) -> list[mujoco.MjModel]:
    """Direct-torque copies of position-servo models (equal models share one copy)."""
    done: dict[int, mujoco.MjModel] = {}
    dofs, keep = actuated_dofs(models[0], spec), mo.friction_share(spec)
    for m in models:
        if id(m) not in done:
            done[id(m)] = to_torque_actuators(copy.copy(m), dofs, keep)
    return [done[id(m)] for m in models]


class _Feedback:
    """Physics steps whose actuator command is computed from the state each starts from
    (:func:`~eaco_jax.gait.quality.motor_torque`): one ``MjData`` per rollout, kept across
    chunks (so the solver's warm start carries over, as on MJX), stepped by ``mj_step``."""

    def __init__(self, motor: ql.MotorParams, nb: int, nu: int, mm: mo.MotorModel,
                 qadr: np.ndarray, dofs: np.ndarray, models, state: np.ndarray) -> None:
        self.mp = ql.MotorParams(*(np.broadcast_to(np.asarray(a, np.float64), (nb, nu))
                                   for a in motor))
        self.mm, self.qadr, self.dofs = mm, qadr, dofs
        self.models = [models] * nb if isinstance(models, mujoco.MjModel) else list(models)
        self.datas = [mujoco.MjData(m) for m in self.models]
        for m, d, row in zip(self.models, self.datas, state, strict=True):
            mujoco.mj_setState(m, d, row, _STATE)

    def run(self, ctrl: np.ndarray):
        """``ctrl`` ``(B, S, nu [+ nv])``: targets (and applied forces) per physics step.
        Returns the states ``(B, S, nstate)``, sensors, joint torques ``(B, S, nu)`` and the
        joint speeds they were computed at (each step's start)."""
        nb, steps = ctrl.shape[:2]
        nu = self.mp.kp.shape[-1]
        m0 = self.models[0]
        out = np.empty((nb, steps, mujoco.mj_stateSize(m0, _STATE)))
        sens = np.empty((nb, steps, m0.nsensordata))
        taus = np.empty((nb, steps, nu))
        speeds = np.empty((nb, steps, nu))
        q = np.empty((nb, nu))
        qdot = np.empty((nb, nu))
        for s in range(steps):
            for b, d in enumerate(self.datas):
                q[b], qdot[b] = d.qpos[self.qadr], d.qvel[self.dofs]
            tau = ql.motor_torque(q, qdot, ctrl[:, s, :nu], self.mp, self.mm, np)
            taus[:, s], speeds[:, s] = tau, qdot
            for b, (m, d) in enumerate(zip(self.models, self.datas, strict=True)):
                d.ctrl[:] = tau[b]
                if ctrl.shape[-1] > nu:
                    d.qfrc_applied[:] = ctrl[b, s, nu:]
                mujoco.mj_step(m, d)
                mujoco.mj_getState(m, d, out[b, s], _STATE)
                sens[b, s] = d.sensordata
        return out, sens, taus, speeds


def nominal_motor(spec: RobotSpec, model: mujoco.MjModel) -> ql.MotorParams:
    """Motor parameters of the model as compiled (no randomisation)."""
    fields = {k: getattr(model, k) for k in VARIED_FIELDS}
    return ql.motor_params(fields, spec, actuated_dofs(model, spec), model.actuator_ctrlrange,
                           xp=np)


def native_trace(
    controls: np.ndarray,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    nthread: int | None = None,
    record_qpos: bool = False,
):
    """Roll out ``controls`` ``(ants, T, nu)`` (held per control step); torso trace
    ``(ants, T + 1, 7)``, plus the joint angles ``(ants, T + 1, nq)`` if ``record_qpos``."""
    out = native_rollout(couple_controls(np.asarray(controls), spec, xp=np), spec, slope_deg,
                         accuracy, nthread=nthread, record_qpos=record_qpos)
    return (out["trace"], out["qpos"]) if record_qpos else out["trace"]


_WORLD_ARRAYS = ("friction", "mass_scale", "stall_scale", "speed_scale")


class _WorldRow:
    """One world's scale arrays with a leading axis of 1 (what model_fields reads)."""

    def __init__(self, **arrays: np.ndarray) -> None:
        for k, v in arrays.items():
            setattr(self, k, np.asarray(v)[None])


def _world_models(base: mujoco.MjModel, spec: RobotSpec, w: dict[str, np.ndarray]):
    """Per rollout ``MjModel`` and motor parameters; equal worlds share one model."""
    cache: dict[bytes, mujoco.MjModel] = {}
    fields_base = {k: getattr(base, k) for k in VARIED_FIELDS}
    geoms, dofs = friction_geom_ids(base, spec), actuated_dofs(base, spec)
    models, motors = [], []
    for i in range(w["friction"].shape[0]):
        row = _WorldRow(**{k: w[k][i] for k in _WORLD_ARRAYS})
        key = b"".join(np.ascontiguousarray(getattr(row, k)).tobytes() for k in _WORLD_ARRAYS)
        fields = model_fields(fields_base, row, geoms, dofs, xp=np)
        if key not in cache:
            m = copy.copy(base)
            for name, v in fields.items():
                getattr(m, name)[...] = v[0]
            cache[key] = m
        models.append(cache[key])
        if not spec.has_motors:  # no datasheet: no motor model (the MJCF's servos as they are)
            continue
        motors.append(ql.motor_params({n: v[0] for n, v in fields.items()}, spec, dofs,
                                      base.actuator_ctrlrange, row.stall_scale[0],
                                      row.speed_scale[0], xp=np))
    if not motors:
        return models, None
    motor = ql.MotorParams(*(np.stack([m[j] for m in motors]) for j in range(len(motors[0]))))
    return models, motor


def native_rollout_callback(
    controls: jax.Array,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    worlds: Worlds | None = None,
    quality: bool = False,
    trace_every: int = 0,
    limits: bool | None = None,
    interpolate: bool | None = None,
    steer: st.SteerInputs | None = None,
):
    """:func:`native_rollout` as a ``jax.pure_callback`` (usable under jit, vmap and scan).

    ``controls`` ``(A, T, nu)``; with ``worlds`` (R of them) every ant runs in every world, rollout
    ``b = a * R + r``. Returns ``trace`` ``(B, T + 1, 7)`` and, with ``quality``, ``acc`` (dict of
    accumulators, leading axis B). The worlds' targets, pushes and initial poses are computed here
    in JAX by the same functions the MJX backend uses. ``trace_every``, ``limits`` and
    ``interpolate``: as :func:`native_rollout`'s (None: the spec's). ``steer``: the heading
    controller (:mod:`eaco_jax.gait.steer`; ``dcontrols`` ``(A, T, nu)`` like ``controls``).
    """
    base = native_model(spec, float(slope_deg), accuracy)
    a, t, nu = controls.shape[-3:]
    lead = controls.shape[:-3]
    if worlds is None:
        r = 1
        ctrl = couple_controls(controls, spec)
        args: dict[str, jax.Array] = {"ctrl": ctrl}
    else:
        r = worlds.size
        steps = jnp.arange(t)
        per_t = jax.vmap(lambda s: world_ctrl_at(controls, s, worlds, spec), out_axes=2)(steps)
        ctrl = per_t.reshape(lead + (a * r, t, nu))
        push = jax.vmap(lambda s: push_at(s, worlds), out_axes=1)(steps)  # (R, T, 3)
        qpos0 = initial_state(spec, base, slope_deg)[1 : 1 + base.nq]
        qadr = np.array([base.joint(n).qposadr[0] for n in spec.joint_names])
        lo, hi = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
        qinit = initial_qpos(jnp.asarray(qpos0, jnp.float32), worlds, qadr, lo, hi)
        tile = lambda x: jnp.broadcast_to(  # noqa: E731
            x[None], lead + (a,) + x.shape).reshape(lead + (a * r,) + x.shape[1:])
        args = {"ctrl": ctrl, "push": tile(push), "qinit": tile(qinit)}
        for k in _WORLD_ARRAYS:
            args[k] = tile(getattr(worlds, k))
    if steer is not None:
        d = jnp.asarray(steer.dcontrols, jnp.float32)
        if worlds is None:
            args["dctrl"] = d
            args["lat"] = jnp.zeros(lead + (a,), jnp.int32)
        else:
            per_w = jax.vmap(lambda s: delayed_at(d, s, worlds), out_axes=-2)(steps)
            args["dctrl"] = per_w.reshape(lead + (a * r, t, nu))  # from (..., A, R, T, nu)
            args["lat"] = tile(worlds.latency)
        if steer.steering.track_turn:  # each ant's commanded rate, in each of its worlds
            args["rates"] = jnp.repeat(jnp.asarray(steer.rates, jnp.float32), r, axis=-1)
    nb = a * r
    shapes: dict[str, jax.ShapeDtypeStruct] = {
        "trace": jax.ShapeDtypeStruct(lead + (nb, t + 1, TRACE_COLUMNS), jnp.float32)}
    if quality:
        el = ql.electrics(spec, spec.control_dt, 1, t, trace_every)
        template = ql.new_acc((nb,), nu, xp=np, motor=el is not None,
                              trace_samples=ql.trace_samples(el))
        shapes["acc"] = {k: jax.ShapeDtypeStruct(lead + v.shape, v.dtype)
                         for k, v in template.items()}
    names = sorted(args)
    trailing = {n: v.ndim - len(lead) - 1 for n, v in args.items()}  # dims after the rollout axis

    def host(*values):
        kw = {n: np.asarray(v) for n, v in zip(names, values, strict=True)}
        extra = kw["ctrl"].shape[:-3]  # seeds / vmapped axes, flattened into the rollout axis
        flat = {n: v.reshape((-1,) + v.shape[v.ndim - trailing[n]:]) for n, v in kw.items()}
        opts: dict = {}
        if worlds is not None:
            models, motor = _world_models(base, spec, {k: flat[k] for k in _WORLD_ARRAYS})
            opts = dict(models=models, motor=motor, qpos_init=flat["qinit"].astype(np.float64),
                        push=flat["push"])
        if steer is not None:
            opts["steer"] = st.SteerInputs(flat["dctrl"], steer.steering, steer.direction,
                                           flat.get("rates"))
            opts["latency"] = flat["lat"]
        out = native_rollout(flat["ctrl"], spec, slope_deg, accuracy, quality=quality,
                             trace_every=trace_every, limits=limits, interpolate=interpolate,
                             **opts)
        res = {"trace": out["trace"].reshape(extra + (nb, t + 1, TRACE_COLUMNS))}
        if quality:
            res["acc"] = {k: v.reshape(extra + (nb,) + v.shape[1:]) for k, v in out["acc"].items()}
        return res

    return jax.pure_callback(host, shapes, *(args[n] for n in names), vmap_method="broadcast_all")


def native_trace_callback(
    controls: jax.Array, spec: RobotSpec, slope_deg: float = 0.0, accuracy: str = "fast"
) -> jax.Array:
    """:func:`native_trace` as a ``jax.pure_callback`` (usable under jit, vmap and scan)."""
    return native_rollout_callback(controls, spec, slope_deg, accuracy)["trace"]
