"""Energy and gait-quality metrics of batched rollouts, accumulated while simulating.

Both backends feed the same functions (``xp`` = ``numpy`` on the host for native MuJoCo,
``jax.numpy`` inside MJX's scan), so the definitions exist once:

* drive torque at a joint during a physics step: ``tau = clip(kp (clip(ctrl) - q) - kd qdot,
  +-stall) - damping * qdot`` with ``q`` before and ``qdot`` after the step (what implicitfast
  applies: the servo force, with the servo's own velocity gain ``kd`` where the MJCF has one,
  plus the joint's damping: the NAO's back-EMF and friction drag, a Menagerie model's joint
  damping);
* mechanical power = sum over joints of ``max(tau * qdot, 0)`` (positive work only: NAO's motors
  do not recover energy); energy = its time integral; mean power = energy / time walked; peak
  power = its largest physics-step value;
* cost of transport = energy / (m g d), ``d`` the distance walked in the desired direction (NaN
  when ``d`` < 1 cm);
* peak joint speed as a fraction of the motor's no-load speed, peak |tau| as a fraction of its
  stall torque, RMS tau per joint as a fraction of its nominal (continuous) torque: above 1 the
  motor would overheat in sustained walking;
* the actuator envelope per joint (:func:`envelope`): RMS and peak |tau| in N m and peak |qdot|
  in rad/s against the datasheet's nominal torque, stall torque and no-load speed, or, for a
  robot without motor data, the peak and RMS torque against the actuator's forcerange (the
  MJCF has no joint speed limit, so the speed is reported without one);
* per control step, from the sole spheres: a sphere is down when it is within 2 mm of the floor,
  a foot is in contact when any of its spheres is down; foot slip = for each foot, the least
  horizontal distance moved between two control steps by a sphere down at both (0 when none
  is), summed over feet and steps (metres). A foot sliding flat moves every sphere by the
  slide; a foot rolling heel-to-toe or pivoting about one sphere keeps that sphere in place
  and counts 0 (the foot's centre, the figure before, swings with the roll); a foot that yaws
  about one sphere while another drags counts 0 too, so the figure is a lower bound on
  sliding (``experiments/nao_slip_audit.py`` splits both figures by spheres down); airborne
  fraction = share of control steps with no foot in contact; minimum foot gap = smallest
  horizontal distance between a left and a right sole-sphere centre minus 16 mm (each foot box
  reaches 8 mm beyond its spheres), so a gap <= 0 means the feet would touch.

* with the robot's electrical data (:mod:`eaco_jax.gait.motors`): motor current per physics
  step (gear efficiency one way driving, the other braking), RMS current per joint against the
  continuous rating, peak current against the current limit, electrical energy (copper loss plus
  shaft power, >= 0 per joint) and electrical cost of transport, the winding temperature after
  the rollout (two-node thermal model from 25 C, exact per control step) and, from the mean
  loss plus the ripple bound, the winding after ten minutes and at steady state of continuous
  walking and the minutes until it reaches the firmware limit.

Everything counts only until the fall (the steps of control step ``k`` count while torso samples
``0..k`` are all upright), the same horizon the fitness uses.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from eaco_jax.gait import motors as mo

G = 9.81
CONTACT_TOL = 0.002  # m above the sole-sphere radius
FOOT_EDGE = 0.008  # m, each foot box's reach beyond its outer sphere centres (nao.xml)
SOLES_PER_FOOT = 4


class MotorParams(NamedTuple):
    """Per actuator ``(..., nu)``: servo gain, force clamp (the MJCF's forcerange: the NAO's
    stall torque), joint damping, no-load speed, nominal torque, control range and the servo's
    velocity gain (0 for a pure position servo)."""

    kp: object
    stall: object
    damping: object
    no_load_speed: object
    nominal: object
    ctrl_lo: object
    ctrl_hi: object
    kd: object = 0.0


def motor_params(fields: dict, spec, act_dofs, ctrlrange, stall_scale=1.0, speed_scale=1.0,
                 xp=jnp) -> MotorParams:
    """:class:`MotorParams` from (possibly per-world) model fields and the spec's datasheet;
    without one the nominal torque is the force limit and the no-load speed unbounded."""
    if spec.has_motors:
        speed, nominal = spec.no_load_speed, spec.nominal_torque
    else:
        speed, nominal = (np.inf,) * spec.nu, spec.force_limit
    return MotorParams(
        kp=xp.asarray(fields["actuator_gainprm"])[..., 0],
        stall=xp.asarray(fields["actuator_forcerange"])[..., 1],
        damping=xp.asarray(fields["dof_damping"])[..., np.asarray(act_dofs)],
        no_load_speed=xp.asarray(speed) * speed_scale,
        nominal=xp.asarray(nominal) * stall_scale,
        ctrl_lo=xp.asarray(ctrlrange[:, 0]),
        ctrl_hi=xp.asarray(ctrlrange[:, 1]),
        kd=-xp.asarray(fields["actuator_biasprm"])[..., 2],
    )


def drive_torque(q, qdot, ctrl, mp: MotorParams, xp=jnp):
    """The torque the drive applies to each joint in a physics step (see module docstring)."""
    u = xp.clip(ctrl, mp.ctrl_lo, mp.ctrl_hi)
    force = xp.clip(mp.kp * (u - q) - mp.kd * qdot, -mp.stall, mp.stall)
    return force - mp.damping * qdot


def motor_torque(q, qdot, ctrl, mp: MotorParams, mm: mo.MotorModel, xp=jnp):
    """With the limits in the physics (:func:`eaco_jax.gait.motors.physics_limits`): the torque
    the motor delivers to each joint through its gears, from ``q`` and ``qdot`` at the start of
    the physics step (:func:`eaco_jax.gait.motors.limited_torque` of the saturated servo). The
    physics applies it as it is (a direct-torque actuator), back-EMF included; only the
    friction share of the joint damping stays implicit."""
    u = xp.clip(ctrl, mp.ctrl_lo, mp.ctrl_hi)
    servo = xp.clip(mp.kp * (u - q), -mp.stall, mp.stall)
    return mo.limited_torque(servo, qdot, mp.stall, mp.no_load_speed, mm, xp)


def new_acc(batch: tuple[int, ...], nu: int, xp=jnp, motor: bool = False,
            trace_samples: int = 0) -> dict:
    """Empty accumulators for a batch of rollouts (``motor``: also the electrical and thermal
    ones of :class:`Electrics`; ``trace_samples``: also the winding and housing temperatures
    above ambient at that many evenly spaced control steps, :attr:`Electrics.trace_every`
    apart, and the first control step at which each winding reached the firmware limit)."""
    z = lambda *s: xp.zeros(batch + s, xp.float32)  # noqa: E731
    acc = {
        "energy": z(), "peak_power": z(), "steps": z(), "ctrl_steps": z(), "air_steps": z(),
        "slip": z(), "min_gap": xp.full(batch, np.inf, xp.float32),
        "peak_speed": z(nu), "peak_torque": z(nu), "sum_tau2": z(nu),
        "peak_tau": z(nu), "peak_qdot": z(nu),
        "prev_xy": z(2, SOLES_PER_FOOT, 2),
        "prev_down": xp.zeros(batch + (2, SOLES_PER_FOOT), bool),
    }
    if motor:
        acc.update({"energy_el": z(), "sum_i2": z(nu), "peak_i": z(nu), "loss_j": z(nu),
                    "therm": z(nu, 2), "loss_blocks": z(mo.BLOCKS, nu)})
        if trace_samples:
            acc["therm_trace"] = z(trace_samples, nu, 2)
            acc["hot_step"] = xp.full(batch + (nu,), -1, xp.int32)
    return acc


class Electrics(NamedTuple):
    """What :func:`add_physics` needs for the electrical and thermal accumulators: the motor
    model, its thermal modes for one control step, physics steps per control step and the
    horizon in control steps (which sets the loss blocks)."""

    model: mo.MotorModel
    modes: mo.Modes
    substeps: int
    horizon: int
    trace_every: int = 0


def electrics(spec, control_dt: float, substeps: int, horizon: int,
              trace_every: int = 0) -> Electrics | None:
    """:class:`Electrics` of a robot (None without electrical data); ``trace_every``: control
    steps between temperature samples (0: no trace)."""
    mm = mo.motor_model(spec)
    if mm is None:
        return None
    return Electrics(mm, mo.modes(mm, control_dt), int(substeps), int(horizon),
                     int(trace_every))


def trace_samples(el: Electrics | None) -> int:
    """Temperature samples a rollout of ``el.horizon`` control steps records."""
    if el is None or not el.trace_every:
        return 0
    return el.horizon // el.trace_every


def add_physics(acc: dict, q, qdot, ctrl, alive, mp: MotorParams, dt: float, xp=jnp,
                el: Electrics | None = None, step0=0, tau=None) -> dict:
    """Accumulate physics steps: ``q`` (before), ``qdot`` (after) ``(B, S, nu)``, ``ctrl``
    ``(B, S, nu)`` or ``(B, 1, nu)``, ``alive`` ``(B, S)``; ``mp`` fields ``(B, 1, nu)``.
    With ``el`` the steps are whole control steps, the first one ``step0``. ``tau``: the joint
    torques the physics applied (:func:`motor_torque`, limits in the physics), else
    :func:`drive_torque`."""
    if tau is None:
        tau = drive_torque(q, qdot, ctrl, mp, xp)
    m = alive[..., None]
    power = xp.sum(xp.maximum(tau * qdot, 0.0), axis=-1)
    power = xp.where(alive, power, 0.0)
    out = dict(acc)
    out["energy"] = acc["energy"] + xp.sum(power, axis=-1) * dt
    out["peak_power"] = xp.maximum(acc["peak_power"], xp.max(power, axis=-1))
    out["steps"] = acc["steps"] + xp.sum(alive, axis=-1)
    speed = xp.where(m, xp.abs(qdot) / mp.no_load_speed, 0.0)
    out["peak_speed"] = xp.maximum(acc["peak_speed"], xp.max(speed, axis=-2))
    torque = xp.where(m, xp.abs(tau) / mp.stall, 0.0)
    out["peak_torque"] = xp.maximum(acc["peak_torque"], xp.max(torque, axis=-2))
    out["sum_tau2"] = acc["sum_tau2"] + xp.sum(xp.where(m, tau * tau, 0.0), axis=-2)
    out["peak_tau"] = xp.maximum(acc["peak_tau"], xp.max(xp.where(m, xp.abs(tau), 0.0), axis=-2))
    out["peak_qdot"] = xp.maximum(acc["peak_qdot"],
                                  xp.max(xp.where(m, xp.abs(qdot), 0.0), axis=-2))
    if el is not None:
        out.update(_add_electrics(acc, tau, qdot, m, dt, el, step0, xp))
    return out


def _add_electrics(acc: dict, tau, qdot, m, dt: float, el: Electrics, step0, xp) -> dict:
    mm = el.model
    i = mo.current(tau, qdot, mm, xp)
    loss = xp.where(m, mo.copper_loss(i, mm, xp), 0.0)  # (B, S, nu)
    p_el = xp.where(m, mo.electrical_power(tau, qdot, i, mm, xp), 0.0)
    b, s, nu = loss.shape
    k = s // el.substeps
    per_ctrl = xp.mean(loss.reshape(b, k, el.substeps, nu), axis=2)  # (B, K, nu) held losses
    ctrl_dt = el.substeps * dt
    blk = (step0 + xp.arange(k)) * mo.BLOCKS // max(el.horizon, 1)
    blk = xp.minimum(blk, mo.BLOCKS - 1)
    if xp is np:
        blocks = np.array(acc["loss_blocks"], copy=True)
        np.add.at(blocks, (slice(None), blk), per_ctrl * ctrl_dt)
    else:
        blocks = acc["loss_blocks"].at[:, blk].add(per_ctrl * ctrl_dt)
    out = {
        "energy_el": acc["energy_el"] + xp.sum(p_el, axis=(-1, -2)) * dt,
        "sum_i2": acc["sum_i2"] + xp.sum(xp.where(m, i * i, 0.0), axis=-2),
        "peak_i": xp.maximum(acc["peak_i"], xp.max(xp.where(m, xp.abs(i), 0.0), axis=-2)),
        "loss_j": acc["loss_j"] + xp.sum(loss, axis=-2) * dt,
        "loss_blocks": blocks.astype(xp.float32),
    }
    if "therm_trace" not in acc:
        out["therm"] = mo.advance(acc["therm"], per_ctrl, el.modes, xp).astype(xp.float32)
        return out
    return out | _trace_steps(acc, per_ctrl, el, step0, xp)


def _trace_steps(acc: dict, per_ctrl, el: Electrics, step0, xp) -> dict:
    """The thermal state control step by control step: samples every ``el.trace_every``
    steps into ``therm_trace``, the first step each winding reaches the firmware limit into
    ``hot_step`` (the modal state in float32 as without a trace)."""
    z, trace, hot = acc["therm"], acc["therm_trace"], acc["hot_step"]
    rise = xp.asarray(el.model.t_limit - el.model.t_ambient, xp.float32)
    n = trace.shape[1]
    if xp is np:
        trace = np.array(trace, copy=True)
    for j in range(per_ctrl.shape[1]):
        z = mo.advance(z, per_ctrl[:, j : j + 1], el.modes, xp).astype(xp.float32)
        temps = mo.temperatures(z, el.modes, xp).astype(xp.float32)  # (B, nu, 2)
        done = step0 + j + 1  # control steps simulated
        hot = xp.where((hot < 0) & (temps[..., 0] >= rise), done - 1, hot)
        slot = xp.clip(done // el.trace_every - 1, 0, n - 1)
        keep = (done % el.trace_every == 0) & (done // el.trace_every <= n)
        if xp is np:
            if keep:
                trace[:, slot] = temps
        else:
            trace = trace.at[:, slot].set(xp.where(keep, temps, trace[:, slot]))
    return {"therm": z, "therm_trace": trace, "hot_step": hot.astype(xp.int32)}


def add_control(acc: dict, soles, alive, normal, radius: float, xp=jnp) -> dict:
    """Accumulate control steps: sole-sphere centres ``soles`` ``(B, K, 8, 3)`` (left foot's four
    first), ``alive`` ``(B, K)``, floor ``normal`` (3,) through the origin. Feet of another
    layout (not four sole spheres on each of two feet: the Menagerie robots) count the control
    steps only; their slip, airborne fraction and foot gap stay NaN."""
    if soles.shape[-2] != 2 * SOLES_PER_FOOT:
        out = dict(acc)
        out["ctrl_steps"] = acc["ctrl_steps"] + xp.sum(alive, axis=-1)
        for k in ("slip", "air_steps", "min_gap"):
            out[k] = xp.full_like(acc[k], np.nan)
        return out
    height = soles @ xp.asarray(normal, xp.float32)  # (B, K, 8)
    feet = height.reshape(height.shape[:-1] + (2, SOLES_PER_FOOT))
    down = feet < radius + CONTACT_TOL  # (B, K, 2, 4) spheres
    contact = xp.any(down, axis=-1)  # (B, K, 2)
    xy = soles[..., :2].reshape(soles.shape[:-2] + (2, SOLES_PER_FOOT, 2))
    slid = xp.where(alive[..., None], _contact_slip(acc, xy, down, xp), 0.0)
    left, right = xy[..., 0, :, None, :], xy[..., 1, None, :, :]
    pair = xp.sqrt(xp.sum((left - right) ** 2, axis=-1))  # (B, K, 4, 4)
    gap = xp.min(pair.reshape(pair.shape[:-2] + (-1,)), axis=-1) - 2 * FOOT_EDGE
    out = dict(acc)
    out["ctrl_steps"] = acc["ctrl_steps"] + xp.sum(alive, axis=-1)
    out["air_steps"] = acc["air_steps"] + xp.sum(alive & ~xp.any(contact, axis=-1), axis=-1)
    out["slip"] = acc["slip"] + xp.sum(slid, axis=(-1, -2))
    out["min_gap"] = xp.minimum(acc["min_gap"], xp.min(xp.where(alive, gap, np.inf), axis=-1))
    out["prev_xy"] = xy[:, -1]
    out["prev_down"] = down[:, -1]
    return out


def _contact_slip(acc: dict, xy, down, xp):
    """Per foot and control step ``(B, K, 2)``: the least horizontal distance moved since the
    previous control step by a sole sphere down at both (0 when no sphere is); ``xy``
    ``(B, K, 2, 4, 2)``, ``down`` ``(B, K, 2, 4)``."""
    prev = xp.concatenate([acc["prev_xy"][:, None], xy[:, :-1]], axis=1)
    prev_d = xp.concatenate([acc["prev_down"][:, None], down[:, :-1]], axis=1)
    both = down & prev_d
    move = xp.sqrt(xp.sum((xy - prev) ** 2, axis=-1))  # (B, K, 2, 4)
    least = xp.min(xp.where(both, move, np.inf), axis=-1)
    return xp.where(xp.any(both, axis=-1), least, 0.0)


def finalize(acc: dict, distance, mass, dt: float, nominal, motor: mo.MotorModel | None = None
             ) -> dict:
    """Metrics (batched like ``acc``) from accumulators, the distance walked in the desired
    direction until the fall, the robot's mass and the actuators' nominal torque (``motor``:
    also the electrical and thermal metrics)."""
    steps = jnp.maximum(acc["steps"], 1.0)
    seconds = steps * dt
    energy = acc["energy"]
    cot = jnp.where(distance > 0.01, energy / (mass * G * jnp.maximum(distance, 0.01)), jnp.nan)
    rms = jnp.sqrt(acc["sum_tau2"] / steps[..., None]) / nominal
    return {
        "energy_j": energy,
        "mean_power_w": energy / seconds,
        "peak_power_w": acc["peak_power"],
        "cost_of_transport": cot,
        "peak_speed_frac": jnp.max(acc["peak_speed"], axis=-1),
        "peak_torque_frac": jnp.max(acc["peak_torque"], axis=-1),
        "joint_peak_speed_frac": acc["peak_speed"],
        "joint_peak_torque_frac": acc["peak_torque"],
        "rms_torque_frac": rms,
        "joint_peak_torque_nm": acc["peak_tau"],
        "joint_rms_torque_nm": jnp.sqrt(acc["sum_tau2"] / steps[..., None]),
        "joint_peak_speed_rad_s": acc["peak_qdot"],
        "foot_slip_m": acc["slip"],
        "airborne_fraction": acc["air_steps"] / jnp.maximum(acc["ctrl_steps"], 1.0),
        "min_foot_gap_m": acc["min_gap"],
    } | (_finalize_electrics(acc, distance, mass, seconds, steps, motor)
         if motor is not None and "therm" in acc else {})


def _finalize_electrics(acc, distance, mass, seconds, steps, mm: mo.MotorModel) -> dict:
    energy = acc["energy_el"]
    md = mo.modes(mm, 1.0)
    temps = mo.temperatures(acc["therm"], md)
    amb = jnp.asarray(mm.t_ambient, jnp.float32)
    power = acc["loss_j"] / seconds[..., None]  # mean copper loss (W) per motor
    ripple = mo.ripple_bound(acc["loss_blocks"], seconds, power, mm)
    hot10 = mo.step_response(mo.TEN_MINUTES, power, mm)[..., 0]
    steady = mo.steady_state(power, mm)[..., 0]
    endurance = mo.minutes_to_limit(power, ripple, mm)
    f32 = lambda x: jnp.asarray(x, jnp.float32)  # noqa: E731
    return {
        "electrical_energy_j": energy,
        "mean_electrical_power_w": energy / seconds,
        "electrical_cot": jnp.where(distance > 0.01,
                                    energy / (mass * G * jnp.maximum(distance, 0.01)), jnp.nan),
        "rms_current_frac": f32(jnp.sqrt(acc["sum_i2"] / steps[..., None]) / mm.i_cont),
        "peak_current_frac": f32(acc["peak_i"] / mm.i_limit),
        "copper_loss_w": f32(power),
        "winding_end_c": f32(amb + temps[..., 0]),
        "winding_ripple_c": f32(ripple),
        "winding_10min_c": f32(amb + hot10 + ripple),
        "winding_steady_c": f32(amb + steady + ripple),
        "endurance_min": f32(endurance),
        "min_endurance_min": f32(jnp.min(endurance, axis=-1)),
        "peak_current_max_frac": f32(jnp.max(acc["peak_i"] / mm.i_limit, axis=-1)),
    } | ({} if "therm_trace" not in acc else {
        "winding_trace_c": f32(amb + acc["therm_trace"][..., 0]),
        "housing_trace_c": f32(amb + acc["therm_trace"][..., 1]),
        "housing_end_c": f32(amb + temps[..., 1]),
        "limit_step": acc["hot_step"],
    })


ENVELOPE_COLUMNS = ("rms_torque_nm", "rms_torque_frac", "peak_torque_nm", "peak_torque_frac",
                    "peak_speed_rad_s", "peak_speed_frac")


def envelope_limits(spec) -> dict[str, object]:
    """What the envelope compares with, per actuator: ``rms`` (the datasheet's nominal torque,
    else the force limit), ``peak`` (stall torque, else the force limit), ``speed`` (no-load
    speed, else None: an MJCF has no joint speed limit) and ``basis`` naming them."""
    if spec.has_motors:
        return {"rms": np.asarray(spec.nominal_torque), "peak": np.asarray(spec.stall_torque),
                "speed": np.asarray(spec.no_load_speed),
                "basis": "motor data: RMS torque / nominal (continuous) torque, peak torque / "
                         "stall torque, peak speed / no-load speed"}
    force = np.asarray(spec.force_limit)
    return {"rms": force, "peak": force, "speed": None,
            "basis": "no motor data: RMS and peak torque / the actuator's forcerange, peak "
                     "speed without a limit (the MJCF has none)"}


def envelope(q: dict, spec) -> dict[str, object]:
    """The actuator envelope of one gait (``q``: :func:`finalize` output with a leading axis of
    1): per joint :data:`ENVELOPE_COLUMNS` (a fraction is None where the limit is missing or
    unbounded), each joint's ``limits``, the worst joint of each fraction and ``overheating``
    (joints whose RMS torque exceeds their motor's nominal torque; only with motor data)."""
    nu = spec.nu
    row = lambda k: np.asarray(q[k], np.float64).reshape(-1, nu)[0]  # noqa: E731
    vals = {"rms": row("joint_rms_torque_nm"), "peak": row("joint_peak_torque_nm"),
            "speed": row("joint_peak_speed_rad_s")}
    lim = envelope_limits(spec)

    def frac(key):
        limit = lim[key]
        if limit is None:
            return [None] * nu
        return [float(a / b) if np.isfinite(b) and b > 0 else None
                for a, b in zip(vals[key], np.asarray(limit, np.float64), strict=True)]

    cols = {"rms_torque_nm": vals["rms"].tolist(), "rms_torque_frac": frac("rms"),
            "peak_torque_nm": vals["peak"].tolist(), "peak_torque_frac": frac("peak"),
            "peak_speed_rad_s": vals["speed"].tolist(), "peak_speed_frac": frac("speed")}
    names = spec.joint_names
    joints = {n: {c: cols[c][j] for c in ENVELOPE_COLUMNS} for j, n in enumerate(names)}

    def limit(key, j):
        v = lim[key]
        return None if v is None or not np.isfinite(v[j]) else float(v[j])

    worst = {}
    for c in ("rms_torque_frac", "peak_torque_frac", "peak_speed_frac"):
        known = [(v, n) for n, v in zip(names, cols[c], strict=True) if v is not None]
        worst[c] = {"joint": max(known)[1], "value": max(known)[0]} if known else None
    hot = ([n for n, v in zip(names, cols["rms_torque_frac"], strict=True)
            if v is not None and v > 1.0] if spec.has_motors else [])
    return {"basis": lim["basis"], "motor_data": bool(spec.has_motors),
            "limits": {n: {"rms_nm": limit("rms", j), "peak_nm": limit("peak", j),
                           "speed_rad_s": limit("speed", j)} for j, n in enumerate(names)},
            "joints": joints, "worst": worst, "overheating": hot}


def envelope_table(env: dict[str, object]) -> str:
    """The envelope as text: one row per joint, then the worst joint of each fraction and the
    joints that would overheat."""
    def cell(v, width):
        return f"{'-':>{width}}" if v is None else f"{v:{width}.2f}"

    rms, peak, speed = (("/nominal", "/stall", "/no-load") if env["motor_data"] else
                        ("/force", "/force", "/limit"))
    lines = [f"actuator envelope ({env['basis']}):",
             f"  {'joint':<16} {'RMS N m':>8} {rms:>8} {'peak N m':>8} {peak:>7} "
             f"{'peak rad/s':>10} {speed:>8}"]
    for name, r in env["joints"].items():
        lines.append(f"  {name:<16} {cell(r['rms_torque_nm'], 8)} {cell(r['rms_torque_frac'], 8)}"
                     f" {cell(r['peak_torque_nm'], 8)} {cell(r['peak_torque_frac'], 7)}"
                     f" {cell(r['peak_speed_rad_s'], 10)} {cell(r['peak_speed_frac'], 8)}")
    worst = [f"{c} {w['joint']} {w['value']:.2f}" for c, w in env["worst"].items() if w]
    lines.append("  worst: " + (", ".join(worst) if worst else "-") + "; overheating: "
                 + (", ".join(env["overheating"]) if env["overheating"] else "none"))
    return "\n".join(lines)


def overheating(rms_torque_frac, joint_names) -> list[str]:
    """Joints whose RMS torque exceeds their motor's nominal (continuous) torque."""
    rms = np.asarray(rms_torque_frac).reshape(-1)
    return [n for n, v in zip(joint_names, rms, strict=True) if v > 1.0]


def sole_sensor_names(spec) -> list[str]:
    """Names of the ``framepos`` sensors :func:`eaco_jax.gait.robot.load_model` adds per sole."""
    return [f"sole_pos_{g}" for g in spec.foot_geoms]


__all__ = ["Electrics", "MotorParams", "add_control", "add_physics",
           "drive_torque", "electrics", "finalize", "motor_params", "motor_torque", "new_acc",
           "overheating", "trace_samples"]
