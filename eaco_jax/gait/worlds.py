"""Randomised simulation conditions ("worlds") for robust gait fitness.

A :class:`RobustConfig` says how far each condition varies; :func:`sample_worlds` draws R worlds
from a key (the same key gives the same worlds). Every ant of a colony is simulated in the same R
worlds (common random numbers, so ants are ranked on equal terms), ants x R in one batched call.

What varies per world, and where it enters the simulation (identically on both backends):

* model fields (MJX: a model batched with ``in_axes`` on these fields, brax
  ``DomainRandomizationVmapWrapper``-style; native: one ``MjModel`` copy per world in the list
  ``mujoco.rollout`` takes): ``geom_friction`` (sliding friction of the floor and the soles, set
  together because MuJoCo uses the larger of a pair), ``body_mass`` and ``body_inertia`` (each
  link scaled by one factor: uniform density change), and the motors within their datasheet
  tolerances (stall torque scales ``actuator_forcerange`` and the servo gain
  ``actuator_gainprm[0]`` / ``actuator_biasprm[1]``; stall / no-load speed scales the
  ``dof_damping`` of the actuated joints). Derived constants (``body_invweight0``, ...) are not
  recomputed, on either backend.
* inputs: joint-target noise (Gaussian per control step and joint) and latency (whole control
  steps) on the commanded targets, an initial-pose offset on the actuated joints, and one
  horizontal push on the torso (a force on the free joint's translational dofs for
  ``push_duration`` seconds, at a random time after the start-up ramp).

Three key streams, kept apart (:data:`STREAMS`, :func:`stream_key`): every world is drawn from
``fold_in(fold_in(PRNGKey(seed), stream id), batch)`` of the run's seed, with stream ids
``optimisation`` 0 (the worlds the search sees; the driver's per-iteration key picks the batch,
:func:`optimisation_key`), ``selection`` 1 (worlds that choose among finalists) and ``test`` 2
(worlds nothing is chosen on: every reported fall rate).

The two HipYawPitch joints share a motor: their motor factors, pose offsets and noisy targets are
equal (the leader's, as on a NAO where LHipYawPitch wins).
"""

from __future__ import annotations

import copy
import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.errors import ProblemError
from eaco_jax.gait.fitness import AGGREGATES
from eaco_jax.gait.walk_engine import RAMP_TIME

FRICTION_GEOMS = "floor"
"""The floor plus every geom of ``spec.foot_geoms`` gets the world's sliding friction."""


#: Where each :class:`RobustConfig` range comes from: ("sourced" | "assumption", the source or
#: why none). A range without a published NAO figure is a documented assumption (issue 30,
#: item 1); docs/motors.md ("Where the ranges come from") has the quotes.
RANGE_SOURCES: dict[str, tuple[str, str]] = {
    "friction": ("assumption", "no NAO foot measurement found; humanoid-foot friction of indoor "
                 "floors 0.82-0.97 and grass 0.53 (Brandao et al. 2017, arXiv:1706.08685) lie "
                 "in the range"),
    "mass": ("assumption", "no per-unit tolerance published; Aldebaran's link masses are CAD "
             "values, symmetrised left/right (doc.aldebaran.com, NAO masses tables)"),
    "motor": ("sourced", "the motor datasheets' tolerances: stall torque +-8 %, no-load speed "
              "+-10 % (robots/nao.json sources.motors)"),
    "target_noise": ("assumption", "white noise per control step; sensor quantisation of the "
                     "12-bit joint encoders (2 pi / 4096 rad a count) accounts for only about "
                     "0.0005 rad std; NAO joint play (B-Human JointPlayProvider: 0.5-1.4 deg on "
                     "a good robot) is slow and systematic, not white"),
    "latency": ("sourced", "NAO V5's DCM cycle is 10 ms and applies a new order at the next "
                "cycle (doc.aldebaran.com, DCM); 0-1 control steps of 20 ms span 0-2 cycles"),
    "init_noise": ("assumption", "no source; 0.01 rad lies below a good NAO's joint play of "
                   "0.5-1.4 deg (B-Human JointPlayProvider)"),
    "push": ("assumption", "no published RoboCup SPL collision impulse; a walking-pace bump of "
             "another 5.2 kg NAO (0.17-0.25 m/s, inelastic) transfers about 0.45-0.65 N s"),
    "push_duration": ("assumption", "a short shove, no source"),
    "joint_play": ("sourced", "B-Human's JointPlayProvider (BHumanCodeRelease): a good NAO V6's "
                   "walking tracking error and play, 0.5-1.4 deg per leg joint; off (0) by "
                   "default, so the worlds stay as every stored gait met them"),
}
#: folded into a world batch's key for the joint-play offsets, so the ten keys every other
#: range draws from (and so every world drawn before joint play existed) stay as they were
JOINT_PLAY_FOLD = 0x7A1E


@dataclasses.dataclass(frozen=True)
class RobustConfig:
    """How a gait is evaluated under ``R`` randomised worlds and how the results combine.

    ``aggregate``: "mean", "worst" or "cvar" (the mean of the worst ``ceil(alpha R)`` worlds).
    Ranges: ``friction`` (sliding friction, uniform), ``mass`` (each link x U(1 -/+ mass)),
    ``motor`` (x the datasheet tolerances of stall torque and no-load speed, uniform),
    ``target_noise`` (rad, std), ``latency`` (control steps, uniform 0..latency),
    ``init_noise`` (rad, std), ``push`` (largest horizontal impulse, N s) over ``push_duration``,
    ``joint_play`` (rad: each world offsets each joint's target by U(-play, play), constant
    over the run: joint play and calibration, the slow error white ``target_noise`` is not).
    ``seed`` is the root of the three world streams (the run's seed); a caller passing no key
    gets batch 0 of its optimisation stream (a deterministic objective).
    """

    R: int = 8
    aggregate: str = "cvar"
    alpha: float = 0.25
    seed: int = 0
    friction: tuple[float, float] = (0.5, 1.0)
    mass: float = 0.10
    motor: float = 1.0
    target_noise: float = 0.005
    latency: int = 1
    init_noise: float = 0.01
    push: float = 0.5
    push_duration: float = 0.1
    joint_play: float = 0.0
    #: fresh worlds at every evaluation (drawn from the driver's key stream); False keeps the
    #: worlds fixed by ``seed``, which overfits them: a gait tuned on fixed worlds falls more
    #: often in fresh ones
    resample: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.R, int) or self.R < 1:
            raise ProblemError(f"robust R must be a positive integer, got {self.R!r}")
        if self.aggregate not in AGGREGATES:
            raise ProblemError(f"robust aggregate must be one of {', '.join(AGGREGATES)}, "
                               f"got {self.aggregate!r}")
        if not 0.0 < self.alpha <= 1.0:
            raise ProblemError(f"robust alpha must be in (0, 1], got {self.alpha}")
        lo, hi = self.friction
        if not 0.0 < lo <= hi:
            raise ProblemError(f"robust friction range must satisfy 0 < lo <= hi, got {lo, hi}")
        for name in ("mass", "motor", "target_noise", "init_noise", "push", "push_duration",
                     "joint_play"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ProblemError(f"robust {name} must be a finite number >= 0, got {v!r}")
        if self.mass >= 1.0:
            raise ProblemError(f"robust mass must be below 1 (a fraction), got {self.mass}")
        if not isinstance(self.latency, int) or self.latency < 0:
            raise ProblemError(f"robust latency must be an integer >= 0, got {self.latency!r}")


@struct.dataclass
class Worlds:
    """R sampled worlds (leading axis R on every array but the noise key and std)."""

    friction: jax.Array  # (R,)
    mass_scale: jax.Array  # (R, nbody)
    stall_scale: jax.Array  # (R, nu)
    speed_scale: jax.Array  # (R, nu)
    latency: jax.Array  # (R,) int32, control steps
    noise_key: jax.Array  # (2,) uint32: the target noise of step t is drawn from fold_in(key, t)
    noise_std: jax.Array  # () rad
    init_dq: jax.Array  # (R, nu) rad
    push_start: jax.Array  # (R,) int32 control step
    push_stop: jax.Array  # (R,) int32 control step (exclusive)
    push_force: jax.Array  # (R, 3) N, world frame
    target_offset: jax.Array  # (R, nu) rad, every control step's target (joint play)

    @property
    def size(self) -> int:
        return int(self.friction.shape[-1])


#: the three key streams of randomised worlds and their ids: ``optimisation`` (the worlds the
#: search sees), ``selection`` (worlds that choose among finalists), ``test`` (worlds nothing
#: is ever chosen on: every reported fall rate)
STREAMS = {"optimisation": 0, "selection": 1, "test": 2}


def world_key(seed: int, iteration: int | jax.Array, stream: int = 0) -> jax.Array:
    """The key of world batch ``iteration`` of stream id ``stream`` (:data:`STREAMS`):
    ``fold_in(fold_in(PRNGKey(seed), stream), iteration)``. Streams are disjoint subtrees of
    the seed's key: two streams share a key only through a threefry collision."""
    return jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), stream), iteration)


def stream_key(seed: int, stream: str, index: int | jax.Array = 0) -> jax.Array:
    """The key of world batch ``index`` of a named stream (:data:`STREAMS`) of a run's seed."""
    if stream not in STREAMS:
        raise ProblemError(f"stream must be one of {', '.join(STREAMS)}, got {stream!r}")
    return world_key(seed, index, STREAMS[stream])


def optimisation_key(seed: int, key: jax.Array) -> jax.Array:
    """The optimisation stream's key for an evaluation the driver keyed with ``key``: the
    driver's key (split off the colony's state, new each iteration and seed row) picks a batch
    of the seed's optimisation stream by its 64 random bits, so the search's worlds stay in
    that stream's subtree, apart from selection and test."""
    words = jax.random.bits(key, (2,), jnp.uint32)
    return jax.random.fold_in(stream_key(seed, "optimisation", words[0]), words[1])


def _couple(x: jax.Array, spec, xp=jnp) -> jax.Array:
    """Copy each coupled joint's leader value onto its follower (last axis = actuators)."""
    for lead, follow in spec.coupled_joints:
        li, fi = spec.joint_names.index(lead), spec.joint_names.index(follow)
        if xp is jnp:
            x = x.at[..., fi].set(x[..., li])
        else:
            x = np.array(x, copy=True)
            x[..., fi] = x[..., li]
    return x


def couple_controls(ctrl, spec, xp=jnp):
    """Targets with the NAO rule applied: a coupled follower takes its leader's command."""
    return _couple(ctrl, spec, xp)


def joint_play_offsets(key: jax.Array, play: float, spec, r: int) -> jax.Array:
    """Each world's constant target offsets ``(r, nu)``, U(-play, play) per joint (a coupled
    follower takes its leader's), from the world batch's ``key``."""
    u = jax.random.uniform(jax.random.fold_in(key, JOINT_PLAY_FOLD), (r, spec.nu), jnp.float32,
                           -1.0, 1.0)
    return _couple(jnp.float32(play) * u, spec)


def sample_worlds(key: jax.Array, cfg: RobustConfig, spec, nbody: int, n_steps: int,
                  r: int | None = None) -> Worlds:
    """``r`` (default ``cfg.R``) worlds drawn from ``key`` within ``cfg``'s ranges."""
    r = cfg.R if r is None else r
    nu = spec.nu
    ks = jax.random.split(key, 10)
    u = lambda k, shape: jax.random.uniform(k, shape, jnp.float32, -1.0, 1.0)  # noqa: E731
    lo, hi = cfg.friction
    tol = dict(spec.motor_tolerances)
    mass = 1.0 + cfg.mass * u(ks[1], (r, nbody))
    mass = mass.at[:, 0].set(1.0)  # the world body
    stall = _couple(1.0 + cfg.motor * tol.get("stall_torque", 0.0) * u(ks[2], (r, nu)), spec)
    speed = _couple(1.0 + cfg.motor * tol.get("no_load_speed", 0.0) * u(ks[3], (r, nu)), spec)
    push_steps = max(1, int(round(cfg.push_duration / spec.control_dt)))
    first = min(int(round(RAMP_TIME / spec.control_dt)), max(0, n_steps - push_steps))
    last = max(first, n_steps - push_steps)
    start = jax.random.randint(ks[7], (r,), first, last + 1, jnp.int32)
    impulse = cfg.push * (0.5 + 0.5 * jax.random.uniform(ks[8], (r,)))
    angle = jax.random.uniform(ks[9], (r,), jnp.float32, 0.0, 2.0 * math.pi)
    force = (impulse / (push_steps * spec.control_dt))[:, None] * jnp.stack(
        [jnp.cos(angle), jnp.sin(angle), jnp.zeros_like(angle)], -1)
    return Worlds(
        friction=jax.random.uniform(ks[0], (r,), jnp.float32, lo, hi),
        mass_scale=mass,
        stall_scale=stall,
        speed_scale=speed,
        latency=jax.random.randint(ks[4], (r,), 0, cfg.latency + 1, jnp.int32),
        noise_key=ks[5],
        noise_std=jnp.asarray(cfg.target_noise, jnp.float32),
        init_dq=_couple(cfg.init_noise * jax.random.normal(ks[6], (r, nu), jnp.float32), spec),
        push_start=start,
        push_stop=start + push_steps,
        push_force=force.astype(jnp.float32),
        target_offset=joint_play_offsets(key, cfg.joint_play, spec, r),
    )


def delayed_at(x: jax.Array, t: jax.Array, worlds: Worlds) -> jax.Array:
    """What each world receives at control step ``t`` of a per-step command ``x``
    ``(..., A, T, nu)``: the row its latency delays, ``(..., A, R, nu)`` (the first row while
    the delay reaches back before the start)."""
    return jnp.take(x, jnp.maximum(t - worlds.latency, 0), axis=-2)


def world_ctrl_at(controls: jax.Array, t: jax.Array, worlds: Worlds, spec) -> jax.Array:
    """Commanded targets ``(A, R, nu)`` at control step ``t`` in each world: the ants' targets
    ``controls`` ``(A, T, nu)`` delayed by the world's latency (:func:`delayed_at`), plus its
    target noise and its joint-play offsets."""
    u = delayed_at(controls, t, worlds)  # (A, R, nu)
    noise = jax.random.normal(jax.random.fold_in(worlds.noise_key, t), u.shape[1:], jnp.float32)
    return _couple(u + worlds.noise_std * noise + worlds.target_offset, spec)


def push_at(t: jax.Array, worlds: Worlds) -> jax.Array:
    """The push force ``(R, 3)`` on the torso during control step ``t``."""
    on = (t >= worlds.push_start) & (t < worlds.push_stop)
    return jnp.where(on[:, None], worlds.push_force, 0.0)


def initial_qpos(qpos0, worlds: Worlds, qpos_adr, lower, upper, xp=jnp):
    """Initial ``qpos`` ``(R, nq)``: the keyframe with each world's joint offsets (in range)."""
    q = xp.broadcast_to(xp.asarray(qpos0), (worlds.init_dq.shape[0],) + tuple(qpos0.shape))
    joints = xp.clip(q[:, qpos_adr] + xp.asarray(worlds.init_dq), lower, upper)
    if xp is jnp:
        return q.at[:, qpos_adr].set(joints)
    q = np.array(q, copy=True)
    q[:, qpos_adr] = joints
    return q


def model_fields(base: dict, worlds, friction_geoms, act_dofs, xp=jnp) -> dict:
    """The varied model fields of each world ``{name: (R, ...)}`` from the base values.

    ``base`` holds the nominal ``geom_friction``, ``body_mass``, ``body_inertia``,
    ``actuator_gainprm``, ``actuator_biasprm``, ``actuator_forcerange`` and ``dof_damping``;
    ``worlds`` any object with the :class:`Worlds` scale arrays (jax or numpy, per ``xp``).
    """
    r = worlds.friction.shape[0]
    rep = lambda a: xp.broadcast_to(xp.asarray(a), (r,) + tuple(np.shape(a)))  # noqa: E731
    stall, speed = xp.asarray(worlds.stall_scale), xp.asarray(worlds.speed_scale)
    fr = rep(base["geom_friction"])
    mask = np.zeros(np.shape(base["geom_friction"])[0], bool)
    mask[list(friction_geoms)] = True
    fr0 = xp.where(xp.asarray(mask)[None, :], xp.asarray(worlds.friction)[:, None], fr[..., 0])
    fr = xp.concatenate([fr0[..., None], fr[..., 1:]], axis=-1)
    mass = xp.asarray(worlds.mass_scale)
    gain = rep(base["actuator_gainprm"])
    bias = rep(base["actuator_biasprm"])
    kp = gain[..., 0] * stall
    gain = xp.concatenate([kp[..., None], gain[..., 1:]], axis=-1)
    bias = xp.concatenate([bias[..., :1], -kp[..., None], bias[..., 2:]], axis=-1)
    damping = rep(base["dof_damping"])
    act = np.zeros(np.shape(base["dof_damping"])[0], bool)
    act[list(act_dofs)] = True
    scale = xp.ones_like(damping)
    scale_act = xp.zeros_like(damping)
    ratio = stall / speed
    if xp is jnp:
        scale_act = scale_act.at[:, np.asarray(act_dofs)].set(ratio)
    else:
        scale_act = np.array(scale_act, copy=True)
        scale_act[:, np.asarray(act_dofs)] = ratio
    damping = damping * xp.where(xp.asarray(act)[None, :], scale_act, scale)
    return {
        "geom_friction": fr,
        "body_mass": rep(base["body_mass"]) * mass,
        "body_inertia": rep(base["body_inertia"]) * mass[..., None],
        "actuator_gainprm": gain,
        "actuator_biasprm": bias,
        "actuator_forcerange": rep(base["actuator_forcerange"]) * stall[..., None],
        "dof_damping": damping,
    }


VARIED_FIELDS = ("geom_friction", "body_mass", "body_inertia", "actuator_gainprm",
                 "actuator_biasprm", "actuator_forcerange", "dof_damping")


def friction_geom_ids(model, spec) -> list[int]:
    """The floor and the feet's contact geoms: the geoms whose friction a world sets."""
    return [model.geom(FRICTION_GEOMS).id] + [model.geom(g).id for g in spec.foot_geoms]


def actuated_dofs(model, spec) -> list[int]:
    return [int(model.joint(n).dofadr[0]) for n in spec.joint_names]


def native_world_models(model, spec, worlds_np) -> list:
    """One ``MjModel`` copy per world with the varied fields set (host, numpy)."""
    base = {k: getattr(model, k) for k in VARIED_FIELDS}
    fields = model_fields(base, worlds_np, friction_geom_ids(model, spec),
                          actuated_dofs(model, spec), xp=np)
    out = []
    for i in range(worlds_np.friction.shape[0]):
        m = copy.copy(model)
        for k, v in fields.items():
            getattr(m, k)[...] = v[i]
        out.append(m)
    return out


__all__ = ["STREAMS", "RobustConfig", "Worlds", "couple_controls", "initial_qpos", "model_fields",
           "native_world_models", "optimisation_key", "push_at", "sample_worlds",
           "stream_key", "world_ctrl_at", "world_key"]
