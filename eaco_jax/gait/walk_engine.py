"""Parameterised open-loop gait generators (pure JAX): NAO walk engine and an ant oscillator.

**Biped walk engine** (the paper's walk engine, §4): one gait cycle of period ``T`` is two steps.
Each foot is in stance for the fraction ``d`` (duty ratio) of the cycle, during which it moves
backward relative to the hip by the step length ``s``; in swing it moves forward again along a
smooth profile and is lifted by ``foot_lift``. The left foot leads the right by half a cycle, so
the body speed is ``s / (d T)``. The hip sways sideways toward the stance foot, the torso leans
by ``torso_pitch``, the arms swing against the legs, and hip-roll / ankle compensations counter
the body sag. The step direction (relative to the desired direction of the problem) and a turn
rate give omnidirectional walking (turning through the one HipYawPitch motor both legs share,
the feet yawing symmetrically). Foot and hip trajectories are turned into joint targets by
the analytic leg IK of :mod:`eaco_jax.gait.ik`. During the first ``RAMP_TIME`` seconds every
amplitude grows linearly from the standing pose, so every gait starts from the same keyframe.
On a slope the feet follow the inclined floor and the soles stay parallel to it.

**Quadruped oscillator** (brax's ant): hips and ankles follow sinusoids of one frequency, with
the diagonal leg pairs in anti-phase (trot) and the phases and amplitudes as parameters.

**Any robot's legs** (``ik="generic"``, and the default where the spec has no ``thigh`` /
``tibia`` geometry): the same biped parameters move each foot point relative to its place in the
standing pose, and damped-least-squares IK on the robot's own leg chains
(:mod:`eaco_jax.gait.ik_generic`, :mod:`eaco_jax.gait.legs`) keeps the sole's standing
orientation (yawed by the turn); the compensations act on the joints whose axes are the hip and
ankle roll and pitch axes. Lengths in the bounds scale with the standing hip height. A
quadruped without the ant's oscillator geometry trots: diagonal pairs half a cycle apart, feet
along the same stance/swing profile, 3-joint legs solved for the foot position.

``joint_targets(params, t, spec, heading)`` returns the ``(nu,)`` position targets in the spec's
joint order; it is written for one parameter vector and one time, vmap it over ants and time.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.gait.ik import leg_ik
from eaco_jax.gait.ik_generic import solve
from eaco_jax.gait.legs import ROLES, arm_swing, leg_set

RAMP_TIME = 1.0
"""Seconds over which the gait amplitudes grow from the standing pose."""


class GaitParams(NamedTuple):
    """Biped walk-engine parameters (the order of ``PARAM_NAMES``); units SI, angles in rad."""

    step_length: float  # s: foot excursion relative to the hip during stance [m]
    hip_height: float  # h: hip joint height above the floor [m]
    duty_ratio: float  # d: fraction of the cycle each foot is on the ground
    period: float  # T: gait cycle (two steps) [s]
    foot_lift: float  # swing-foot clearance [m]
    step_width: float  # extra lateral foot offset beyond the hip width [m]
    lateral_sway: float  # amplitude of the sideways hip shift toward the stance foot [m]
    torso_pitch: float  # forward lean of the torso [rad]
    arm_swing: float  # shoulder-pitch amplitude, against the legs [rad]
    hip_roll_comp: float  # extra stance-leg hip roll (mirrored on the right) [rad]
    ankle_pitch_comp: float  # constant ankle-pitch offset, both feet [rad]
    ankle_roll_comp: float  # constant ankle-roll offset (mirrored) [rad]
    direction: float  # step direction relative to the desired heading [rad]
    turn_rate: float  # yaw rate the feet impose [rad/s]


PARAM_NAMES: tuple[str, ...] = GaitParams._fields
_BOUNDS = {
    "step_length": (0.0, 0.16),
    "hip_height": (0.17, 0.24),
    "duty_ratio": (0.5, 0.8),
    "period": (0.25, 1.0),
    "foot_lift": (0.0, 0.05),
    "step_width": (-0.01, 0.04),
    "lateral_sway": (0.0, 0.04),
    "torso_pitch": (-0.1, 0.4),
    "arm_swing": (0.0, 0.8),
    "hip_roll_comp": (-0.15, 0.15),
    "ankle_pitch_comp": (-0.2, 0.2),
    "ankle_roll_comp": (-0.15, 0.15),
    "direction": (-0.5, 0.5),
    "turn_rate": (-0.3, 0.3),
}
LOWER = np.array([_BOUNDS[n][0] for n in PARAM_NAMES], np.float32)
UPPER = np.array([_BOUNDS[n][1] for n in PARAM_NAMES], np.float32)

ANT_PARAM_NAMES: tuple[str, ...] = (
    "frequency",  # oscillation frequency [Hz]
    "hip_amplitude",  # [rad]
    "ankle_amplitude",  # [rad]
    "ankle_offset",  # added to the standing ankle bend [rad]
    "ankle_phase",  # phase of the ankles relative to the hips [rad]
    "pair_phase",  # phase of the second diagonal pair relative to the first [rad]
    "hip_bias",  # constant hip offset (turning) [rad]
)
ANT_LOWER = np.array([0.5, 0.0, 0.0, -0.3, -math.pi, -math.pi, -0.3], np.float32)
ANT_UPPER = np.array([4.0, 0.5, 0.4, 0.3, math.pi, math.pi, 0.3], np.float32)


TROT_PARAM_NAMES: tuple[str, ...] = (
    "step_length",  # foot excursion relative to the hip during stance [m]
    "body_height",  # hip height above the foot points [m]
    "duty_ratio",  # fraction of the cycle each foot is on the ground
    "period",  # gait cycle [s]
    "foot_lift",  # swing-foot clearance [m]
    "stance_width",  # extra lateral foot offset, outward [m]
    "direction",  # step direction relative to the desired heading [rad]
    "body_pitch",  # nose-down pitch of the torso [rad]
)
# lengths in units of the standing hip height (TROT_LENGTHS), the rest as they are
_TROT_BOUNDS = {
    "step_length": (0.0, 1.0), "body_height": (0.75, 1.05), "duty_ratio": (0.35, 0.75),
    "period": (0.15, 0.8), "foot_lift": (0.0, 0.4), "stance_width": (-0.1, 0.15),
    "direction": (-0.5, 0.5), "body_pitch": (-0.15, 0.15),
}
TROT_LENGTHS = ("step_length", "body_height", "foot_lift", "stance_width")
BIPED_LENGTHS = ("step_length", "hip_height", "foot_lift", "step_width", "lateral_sway")
REF_HIP_HEIGHT = 0.22
"""Standing hip height [m] the biped bounds are written for (the NAO's); other robots' length
bounds scale by their own standing hip height over this."""
IK_CHOICES = ("auto", "analytic", "generic")


def uses_analytic_ik(spec, ik: str = "auto") -> bool:
    """Whether the biped engine uses the NAO-type analytic IK: ``auto`` where the spec has its
    ``thigh`` and ``tibia`` geometry, else the generic IK on the robot's own leg chains."""
    if ik not in IK_CHOICES:
        raise ConfigError(f"ik must be one of {', '.join(IK_CHOICES)}, got {ik!r}")
    has = {"thigh", "tibia", "foot_height", "stand_hip_height"} <= set(dict(spec.geometry))
    if ik == "analytic" and not has:
        raise ConfigError(f"robot {spec.name} has no thigh/tibia/foot_height/stand_hip_height "
                          "geometry for the analytic IK; use ik='generic'")
    return has if ik == "auto" else ik == "analytic"


def _trots(spec) -> bool:
    return spec.gait == "quadruped" and "leg1_x_sign" not in dict(spec.geometry)


def stand_hip_height(spec) -> float:
    """Hip height over the foot points when standing [m]: the spec's ``stand_hip_height``
    geometry where given, else computed from the standing pose through the leg chains."""
    geo = dict(spec.geometry)
    return float(geo["stand_hip_height"]) if "stand_hip_height" in geo else (
        leg_set(spec).stand_height)


def bounds(spec, ik: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Parameter bounds ``(lower, upper)`` of the gait generator for this robot (a biped's
    with the leg IK ``ik``, :func:`uses_analytic_ik`)."""
    if spec.gait == "biped":
        if uses_analytic_ik(spec, ik):
            return LOWER, UPPER
        scale = np.array([stand_hip_height(spec) / REF_HIP_HEIGHT if n in BIPED_LENGTHS
                          else 1.0 for n in PARAM_NAMES], np.float32)
        return LOWER * scale, UPPER * scale
    if _trots(spec):
        h = stand_hip_height(spec)
        scale = np.array([h if n in TROT_LENGTHS else 1.0 for n in TROT_PARAM_NAMES])
        lo = np.array([_TROT_BOUNDS[n][0] for n in TROT_PARAM_NAMES]) * scale
        hi = np.array([_TROT_BOUNDS[n][1] for n in TROT_PARAM_NAMES]) * scale
        return lo.astype(np.float32), hi.astype(np.float32)
    if spec.gait == "quadruped":
        return ANT_LOWER, ANT_UPPER
    raise ValueError(f"no gait generator for gait kind {spec.gait!r} (robot {spec.name})")


def param_names(spec) -> tuple[str, ...]:
    if spec.gait == "biped":
        return PARAM_NAMES
    return TROT_PARAM_NAMES if _trots(spec) else ANT_PARAM_NAMES


def gait_vector(params, dim: int, what: str = "a gait") -> np.ndarray:
    """One gait's parameters as a float32 ``(dim,)`` vector, or one :class:`ProblemError` line
    saying whether the shape or the values are wrong (which entries are NaN or infinite)."""
    p = np.asarray(params, np.float32).reshape(-1)
    if p.shape != (dim,):
        raise ProblemError(f"{what} needs {dim} finite parameters, got shape {p.shape}")
    bad = np.flatnonzero(~np.isfinite(p))
    if bad.size:
        where = ", ".join(str(int(i)) for i in bad[:5]) + (" ..." if bad.size > 5 else "")
        raise ProblemError(f"{what} needs {dim} finite parameters, got NaN or infinite at "
                           f"index {where}")
    return p


def _smoothstep(u: jnp.ndarray) -> jnp.ndarray:
    return u * u * (3.0 - 2.0 * u)


def _foot(phase: jnp.ndarray, d: jnp.ndarray):
    """Normalised foot excursion xi in [-0.5, 0.5] (+ = forward), lift profile, stance bump."""
    stance = phase < d
    u_st = jnp.clip(phase / d, 0.0, 1.0)
    u_sw = jnp.clip((phase - d) / (1.0 - d), 0.0, 1.0)
    xi = jnp.where(stance, 0.5 - u_st, -0.5 + _smoothstep(u_sw))
    lift = jnp.where(stance, 0.0, jnp.sin(jnp.pi * u_sw))
    bump = jnp.where(stance, jnp.sin(jnp.pi * u_st), 0.0)
    return xi, lift, bump


class _BipedProfile(NamedTuple):
    """The biped walk's timing at one instant, shared by the analytic and the generic engine."""

    ramp: jnp.ndarray  # 0 -> 1 over RAMP_TIME: the walk fades in from the standing pose
    slope: float  # ground slope [rad]
    tan_slope: float
    s: jnp.ndarray  # step length so far [m]
    h: jnp.ndarray  # hip height so far [m]
    sway: jnp.ndarray  # lateral sway of the feet [m]
    cdir: jnp.ndarray  # cos / sin of the stepping direction (heading + offset)
    sdir: jnp.ndarray
    psi: jnp.ndarray  # foot yaw of the left foot relative to the torso (right: -psi) [rad]
    feet: tuple  # (xi, lift, bump) of the left, then the right foot (see _foot)


def _biped_profile(p: GaitParams, t: jnp.ndarray, h0: float, heading: float,
                   slope_deg: float) -> _BipedProfile:
    ramp = jnp.clip(t / RAMP_TIME, 0.0, 1.0)
    slope = math.radians(slope_deg)
    phase_l = jnp.mod(t / p.period, 1.0)
    phase_r = jnp.mod(phase_l + 0.5, 1.0)
    sway = p.lateral_sway * ramp * jnp.cos(2 * jnp.pi * (phase_l - p.duty_ratio / 2))
    # the torso starts facing +x; the feet step along the desired heading plus the offset
    cdir, sdir = jnp.cos(heading + p.direction), jnp.sin(heading + p.direction)
    feet = (_foot(phase_l, p.duty_ratio), _foot(phase_r, p.duty_ratio))
    psi = p.turn_rate * p.duty_ratio * p.period * ramp * (feet[0][0] - feet[1][0]) / 2.0
    return _BipedProfile(ramp, slope, math.tan(slope), p.step_length * ramp,
                         h0 + (p.hip_height - h0) * ramp, sway, cdir, sdir, psi, feet)


def _biped_targets(
    params: jnp.ndarray, t: jnp.ndarray, spec, heading: float, slope_deg: float
) -> jnp.ndarray:
    p = GaitParams(*[params[i] for i in range(len(PARAM_NAMES))])
    thigh, tibia = spec.geom("thigh"), spec.geom("tibia")
    foot_h = spec.geom("foot_height")
    pr = _biped_profile(p, t, spec.geom("stand_hip_height"), heading, slope_deg)
    ramp, slope, tan_slope, h, sway = pr.ramp, pr.slope, pr.tan_slope, pr.h, pr.sway
    cdir, sdir, psi = pr.cdir, pr.sdir, pr.psi
    out = jnp.asarray(spec.stand_ctrl, jnp.float32)
    legs = _biped_legs(spec)
    if legs.joint_index.shape[1] != 6:
        raise ConfigError(f"robot {spec.name}: the analytic leg IK needs 6 joints per leg "
                          "(hip yaw, roll, pitch, knee, ankle pitch, roll); use ik='generic'")
    leg_of = {float(side): k for k, side in enumerate(legs.side.tolist())}
    arms = arm_swing(spec)
    # One motor drives both HipYawPitch joints (robots/nao.xml): the feet yaw by +psi (left) and
    # -psi (right) relative to the torso, which turns the body by the stance foot's yaw change.
    for i, ((xi, lift, bump), sign) in enumerate(zip(pr.feet, (1.0, -1.0), strict=True)):
        along = pr.s * xi
        ankle_x = along * cdir
        ankle = jnp.stack([
            ankle_x,
            sign * p.step_width * ramp + along * sdir - sway,
            # on a slope (rising along +x) a foot ahead of the hip lands higher
            -(h - foot_h) + p.foot_lift * ramp * lift + ankle_x * tan_slope,
        ])
        q = leg_ik(ankle, sign * psi, thigh, tibia)
        hip_roll = q[1] + sign * p.hip_roll_comp * ramp * bump
        hip_pitch = q[2] - p.torso_pitch * ramp
        ankle_pitch = q[4] + p.ankle_pitch_comp * ramp - slope  # sole parallel to the floor
        ankle_roll = q[5] + sign * p.ankle_roll_comp * ramp
        values = (psi, hip_roll, hip_pitch, q[3], ankle_pitch, ankle_roll)  # RHipYawPitch: -z
        # the leg chain's joints, torso to foot: yaw, roll, pitch, knee, ankle pitch, roll
        for j, v in zip(legs.joint_index[leg_of[sign]].tolist(), values, strict=True):
            out = out.at[j].set(v)
        if arms:  # the arm swings against the leg on its own side
            j, arm_sign = arms[i]
            out = out.at[j].add(arm_sign * 2.0 * p.arm_swing * ramp * xi)
    lo = jnp.asarray(spec.joint_lower, jnp.float32)
    hi = jnp.asarray(spec.joint_upper, jnp.float32)
    return jnp.clip(out, lo, hi)


def _rot_z(angle: jnp.ndarray) -> jnp.ndarray:
    c, s_ = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(angle), jnp.zeros_like(angle)
    return jnp.stack([jnp.stack([c, -s_, z]), jnp.stack([s_, c, z]), jnp.stack([z, z, o])])


def _solve_legs(legs, targets: jnp.ndarray, rots: jnp.ndarray | None) -> jnp.ndarray:
    """Joint angles ``(L, n)`` of every leg (vmapped IK) from the standing pose."""
    q0 = jnp.asarray(legs.stand_q)
    if rots is None:
        return jax.vmap(lambda c, p, q: solve(c, p, q)[0])(legs.chain, targets, q0)
    return jax.vmap(lambda c, p, q, r: solve(c, p, q, r)[0])(legs.chain, targets, q0, rots)


class BipedFeet(NamedTuple):
    """The biped engine's task-space targets at one time, legs ordered (left, right)."""

    delta: jnp.ndarray  # (2, 3) foot point relative to its standing place, torso axes [m]
    yaw: jnp.ndarray  # (2,) foot yaw relative to the torso [rad]
    offsets: jnp.ndarray  # (2, 4) joint offsets by role (legs.ROLES) about +torso axes [rad]
    arm: jnp.ndarray  # (2,) shoulder-pitch swing of the arm on each side [rad]


def biped_feet(
    params: jnp.ndarray, t: jnp.ndarray, spec, heading: float = 0.0, slope_deg: float = 0.0
) -> BipedFeet:
    """Where the walk engine puts each foot at time ``t``, before any IK (the same profile as
    the analytic engine's ankle targets, relative to the standing pose)."""
    p = GaitParams(*[params[i] for i in range(len(PARAM_NAMES))])
    h0 = stand_hip_height(spec)
    pr = _biped_profile(p, t, h0, heading, slope_deg)
    ramp, slope, tan_slope, h, sway = pr.ramp, pr.slope, pr.tan_slope, pr.h, pr.sway
    cdir, sdir, psi = pr.cdir, pr.sdir, pr.psi
    delta, yaw, offsets, arm = [], [], [], []
    for (xi, lift, bump), sign in zip(pr.feet, (1.0, -1.0), strict=True):
        along = pr.s * xi
        dx = along * cdir
        delta.append(jnp.stack([
            dx,
            sign * p.step_width * ramp + along * sdir - sway,
            -(h - h0) + p.foot_lift * ramp * lift + dx * tan_slope,
        ]))
        yaw.append(sign * psi)
        # hip roll, hip pitch, ankle pitch, ankle roll (legs.ROLES), about the torso's axes
        offsets.append(jnp.stack([sign * p.hip_roll_comp * ramp * bump, -p.torso_pitch * ramp,
                                  p.ankle_pitch_comp * ramp - slope,
                                  sign * p.ankle_roll_comp * ramp]))
        arm.append(2.0 * p.arm_swing * ramp * xi)
    return BipedFeet(jnp.stack(delta), jnp.stack(yaw), jnp.stack(offsets), jnp.stack(arm))


def _biped_legs(spec):
    legs = leg_set(spec)
    if len(legs.feet) != 2 or sorted(legs.side.tolist()) != [-1.0, 1.0]:
        raise ProblemError(f"robot {spec.name}: a biped needs one left and one right foot, "
                           f"found {list(legs.feet)}; name two feet in the spec")
    return legs


def _biped_targets_generic(
    params: jnp.ndarray, t: jnp.ndarray, spec, heading: float, slope_deg: float
) -> jnp.ndarray:
    """The biped walk engine on the robot's own leg chains (generic IK)."""
    legs = _biped_legs(spec)
    feet = biped_feet(params, t, spec, heading, slope_deg)
    order = [0 if side > 0 else 1 for side in legs.side.tolist()]  # leg k -> (left, right)
    targets = jnp.asarray(legs.stand_pos) + feet.delta[jnp.asarray(order)]
    rots = jnp.stack([_rot_z(feet.yaw[i]) @ jnp.asarray(legs.stand_rot[k])
                      for k, i in enumerate(order)])
    q = _solve_legs(legs, targets, rots)
    out = jnp.asarray(spec.stand_ctrl, jnp.float32)
    arms = arm_swing(spec)
    for k, i in enumerate(order):
        qk = q[k]
        for r in range(legs.role_index.shape[1]):
            j = int(legs.role_index[k, r])
            if j >= 0:
                qk = qk.at[j].add(float(legs.role_sign[k, r]) * feet.offsets[i, r])
        out = out.at[legs.joint_index[k]].set(qk)
        if arms:  # the arm swings against the leg on its side
            j, arm_sign = arms[i]
            out = out.at[j].add(arm_sign * feet.arm[i])
    lo = jnp.asarray(spec.joint_lower, jnp.float32)
    hi = jnp.asarray(spec.joint_upper, jnp.float32)
    return jnp.clip(out, lo, hi)


def _trot_targets(params: jnp.ndarray, t: jnp.ndarray, spec, heading: float) -> jnp.ndarray:
    """Quadruped trot on the robot's own legs: diagonal pairs half a cycle apart, generic IK
    for the foot positions."""
    step, height, duty, period, lift_h, width, direction, pitch = (
        params[i] for i in range(len(TROT_PARAM_NAMES)))
    legs = leg_set(spec)
    h0 = stand_hip_height(spec)
    ramp = jnp.clip(t / RAMP_TIME, 0.0, 1.0)
    s = step * ramp
    h = h0 + (height - h0) * ramp
    cdir, sdir = jnp.cos(heading + direction), jnp.sin(heading + direction)
    c, sn = jnp.cos(pitch * ramp), jnp.sin(pitch * ramp)
    to_torso = jnp.stack([jnp.stack([c, 0.0 * c, -sn]), jnp.array([0.0, 1.0, 0.0]),
                          jnp.stack([sn, 0.0 * c, c])])  # R_y(pitch)^T: torso pitched nose-down
    targets = []
    for k in range(len(legs.feet)):
        pair = 0.0 if legs.side[k] * legs.front[k] > 0 else 0.5  # FL+RR, then FR+RL
        xi, lift, _ = _foot(jnp.mod(t / period + pair, 1.0), duty)
        along = s * xi
        delta = jnp.stack([along * cdir, float(legs.side[k]) * width * ramp + along * sdir,
                           -(h - h0) + lift_h * ramp * lift])
        targets.append(to_torso @ (jnp.asarray(legs.stand_pos[k]) + delta))
    q = _solve_legs(legs, jnp.stack(targets), None)
    out = jnp.asarray(spec.stand_ctrl, jnp.float32)
    for k in range(len(legs.feet)):
        out = out.at[legs.joint_index[k]].set(q[k])
    lo = jnp.asarray(spec.joint_lower, jnp.float32)
    hi = jnp.asarray(spec.joint_upper, jnp.float32)
    return jnp.clip(out, lo, hi)


def _ant_targets(params: jnp.ndarray, t: jnp.ndarray, spec) -> jnp.ndarray:
    freq, hip_amp, ankle_amp, ankle_off, ankle_phase, pair_phase, hip_bias = (
        params[i] for i in range(len(ANT_PARAM_NAMES)))
    ramp = jnp.clip(t / RAMP_TIME, 0.0, 1.0)
    geo = dict(spec.geometry)
    out = jnp.asarray(spec.stand_ctrl, jnp.float32)
    names = spec.joint_names
    for leg, pair in ((1, 0.0), (2, 1.0), (3, 0.0), (4, 1.0)):
        phi = 2 * jnp.pi * freq * t + pair * pair_phase
        x_sign = geo[f"leg{leg}_x_sign"]
        stand = spec.stand_ctrl[names.index(f"ankle_{leg}")]
        bend = math.copysign(1.0, stand)
        hip = hip_bias + x_sign * hip_amp * ramp * jnp.sin(phi)
        ankle = stand + bend * (ankle_off + ankle_amp * jnp.sin(phi + ankle_phase)) * ramp
        out = out.at[names.index(f"hip_{leg}")].set(hip)
        out = out.at[names.index(f"ankle_{leg}")].set(ankle)
    lo = jnp.asarray(spec.joint_lower, jnp.float32)
    hi = jnp.asarray(spec.joint_upper, jnp.float32)
    return jnp.clip(out, lo, hi)


def joint_targets(
    params: jnp.ndarray, t: jnp.ndarray, spec, heading: float = 0.0, slope_deg: float = 0.0,
    ik: str = "auto",
) -> jnp.ndarray:
    """Position targets ``(nu,)`` at time ``t`` for one parameter vector (vmap over ants/time).

    ``heading`` (rad) is the desired walking direction relative to the torso's initial +x;
    ``slope_deg`` the floor slope (rising along +x), which the biped's feet follow; ``ik`` the
    biped's leg IK (:func:`uses_analytic_ik`).
    """
    if spec.gait == "biped":
        if uses_analytic_ik(spec, ik):
            return _biped_targets(params, t, spec, heading, slope_deg)
        return _biped_targets_generic(params, t, spec, heading, slope_deg)
    if _trots(spec):
        return _trot_targets(params, t, spec, heading)
    if spec.gait == "quadruped":
        return _ant_targets(params, t, spec)
    raise ValueError(f"no gait generator for gait kind {spec.gait!r} (robot {spec.name})")


def control_sequence(
    params: jnp.ndarray, n_steps: int, spec, heading: float = 0.0, slope_deg: float = 0.0,
    ik: str = "auto",
) -> jnp.ndarray:
    """Targets ``(n_steps, nu)`` at the control instants ``k * control_dt`` for one gait."""
    times = jnp.arange(n_steps, dtype=jnp.float32) * spec.control_dt
    return jax.vmap(lambda t: joint_targets(params, t, spec, heading, slope_deg, ik))(times)


def stand_pose(spec, slope_deg: float = 0.0) -> np.ndarray:
    """The pose every gait starts from: the standing keyframe, a biped's soles parallel to the
    floor (each leg's ankle-pitch joint, :data:`legs.ROLES`, turned by the slope)."""
    pose = np.asarray(spec.stand_ctrl, np.float64).copy()
    if spec.gait == "biped" and slope_deg != 0.0:
        legs = leg_set(spec)
        r = ROLES.index("ankle_pitch")
        for k in range(len(legs.feet)):
            j = int(legs.role_index[k, r])
            if j >= 0:
                pose[int(legs.joint_index[k, j])] -= float(legs.role_sign[k, r]) * math.radians(
                    slope_deg)
    return pose


def gait_speed(params: jnp.ndarray) -> jnp.ndarray:
    """Nominal walking speed ``s / (d T)`` of biped parameters (what the engine asks for)."""
    return params[..., 0] / (params[..., 2] * params[..., 3])
