"""A forward gait searched for walking *while steered*: each randomised world carries a command.

The route walker (:mod:`eaco_jax.gait.walk_route`) never walks the stored forward gait as it
was searched: it overwrites its ``turn_rate`` with the heading error x ``steer_gain`` (clamped
to ``max_steer``) and scales its ``step_length`` down to ``min_step`` of itself as the error
grows, changing both once per step cycle. A gait searched only walking straight falls there.

:class:`SteeredGaitProblem` is a :class:`~eaco_jax.problems.gait.GaitProblem` whose robust
evaluation walks each ant in R randomised worlds (the optimisation stream, as the plain
problem's) where every world also carries a steering schedule: ``segments`` equal stretches of
the horizon, each with its own command drawn from the controller's range
(:func:`sample_commands`: a heading error uniform in +/- ``error_deg`` mapped through the
controller's rule, so the (turn, step) pairs are those the walker asks for), blended at each
change over ``blend_cycles`` of the gait's period while the phase runs on, as the walker does.
The commands are drawn from the world batch's own key, so they belong to its stream.
The physics is the route walker's by default (``walker_physics``: the scene model's position
servos, targets held per control step), not the spec's motor limits and interpolated targets:
gaits searched in the spec's physics fell in about half of the walker's tuning walks.

Fitness per world (maximised): the forward progress in the torso's own frame (metres walked
along its heading, whatever the turn, until the fall or the horizon), minus ``fall_cost`` if
it fell, so a fall ranks below any walk without one (no fall first, progress second); the
worlds are combined by the robust config's aggregate (CVaR, worst, mean).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.errors import ProblemError
from eaco_jax.gait.rollout_mjx import mjx_rollout
from eaco_jax.gait.rollout_native import native_rollout_callback
from eaco_jax.gait.walk_engine import PARAM_NAMES, joint_targets
from eaco_jax.gait.walk_route import Controller
from eaco_jax.gait.worlds import Worlds
from eaco_jax.problems.gait import GaitProblem, body_frame_speeds, make_gait_problem

STEP = PARAM_NAMES.index("step_length")
TURN = PARAM_NAMES.index("turn_rate")
PERIOD = PARAM_NAMES.index("period")
COMMAND_FOLD = 2**30
"""``fold_in`` constant of a world batch's noise key that draws its commands (the target
noise of control step ``t`` uses ``fold_in(noise_key, t)``, ``t`` < 2**24: no overlap)."""


@dataclasses.dataclass(frozen=True)
class SteerConfig:
    """The steering commands a world carries (rates in rad/s, angles in deg).

    The rule from heading error to command is the route controller's
    (:class:`~eaco_jax.gait.walk_route.Controller`: the defaults are its defaults, a test
    checks they agree): ``turn_rate`` = error x ``steer_gain`` clamped to ``max_steer``; the
    step length full up to ``slow_deg`` of error, ``min_step`` of itself from ``stop_deg``.
    ``error_deg``: the heading errors drawn, uniform in +/- this (at most 180; beyond
    ``stop_deg`` the command saturates). ``segments``: commands per rollout (one change
    between each).
    ``fall_cost``: metres subtracted from a world's progress when it falls (None: the
    horizon x 2 m/s, more than any NAO walk covers, so a fall ranks below every non-fall)."""

    segments: int = 3
    error_deg: float = 75.0
    # the route walker's rule, with its defaults (one source: walk_route.Controller)
    steer_gain: float = Controller.steer_gain
    max_steer: float = Controller.max_steer
    slow_deg: float = Controller.slow_deg
    stop_deg: float = Controller.stop_deg
    min_step: float = Controller.min_step
    blend_cycles: float = Controller.blend_cycles
    fall_cost: float | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # NumPy scalars as Python's (JSON, hashing)
            if isinstance(getattr(self, f.name), np.generic):
                object.__setattr__(self, f.name, getattr(self, f.name).item())
        if not _integer(self.segments) or self.segments < 1:
            raise ProblemError(f"steer segments must be an integer >= 1, got {self.segments!r}")
        for name in ("error_deg", "steer_gain", "max_steer", "stop_deg", "blend_cycles"):
            v = getattr(self, name)
            if not (_real(v) and math.isfinite(v) and v > 0):
                raise ProblemError(f"steer {name} must be a finite number > 0, got {v!r}")
        if self.error_deg > 180:
            raise ProblemError(f"steer error_deg must be <= 180 (a heading error wraps at 180), "
                               f"got {self.error_deg}")
        for name in ("slow_deg", "min_step", "fall_cost"):
            v = getattr(self, name)
            if not (_real(v) or (name == "fall_cost" and v is None)):
                raise ProblemError(f"steer {name} must be a number"
                                   f"{' >= 0 or None' if name == 'fall_cost' else ''}, got {v!r}")
        if not 0 <= self.slow_deg < self.stop_deg:
            raise ProblemError(f"steer slow_deg must be in [0, stop_deg={self.stop_deg}), "
                               f"got {self.slow_deg}")
        if not 0 < self.min_step <= 1:
            raise ProblemError(f"steer min_step must be in (0, 1], got {self.min_step}")
        if self.fall_cost is not None and not (math.isfinite(self.fall_cost)
                                               and self.fall_cost >= 0):
            raise ProblemError(f"steer fall_cost must be a finite number >= 0 or None, got "
                               f"{self.fall_cost!r}")


def _integer(v: Any) -> bool:
    """An integer, not a bool."""
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _real(v: Any) -> bool:
    """A real number, not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def command_of(error: jax.Array, cfg: SteerConfig) -> tuple[jax.Array, jax.Array]:
    """The controller's (``turn_rate``, step fraction) for heading errors [rad] (any shape)."""
    turn = jnp.clip(cfg.steer_gain * error, -cfg.max_steer, cfg.max_steer)
    u = (jnp.degrees(jnp.abs(error)) - cfg.slow_deg) / (cfg.stop_deg - cfg.slow_deg)
    step = 1.0 - (1.0 - cfg.min_step) * jnp.clip(u, 0.0, 1.0)
    return turn, step


def sample_commands(key: jax.Array, cfg: SteerConfig, r: int) -> tuple[jax.Array, jax.Array]:
    """``turn`` and ``step`` fractions ``(r, segments)`` of ``r`` worlds from ``key``."""
    lim = math.radians(cfg.error_deg)
    error = jax.random.uniform(key, (r, cfg.segments), jnp.float32, -lim, lim)
    return command_of(error, cfg)


def world_commands(worlds: Worlds, cfg: SteerConfig) -> tuple[jax.Array, jax.Array]:
    """The commands of a world batch, drawn from its own key (so from its stream)."""
    return sample_commands(jax.random.fold_in(worlds.noise_key, COMMAND_FOLD), cfg, worlds.size)


def steered_params(params: jax.Array, turn: jax.Array, step: jax.Array, times: jax.Array,
                   horizon: float, blend_cycles: float) -> jax.Array:
    """Per-instant parameters ``(T, P)`` of one gait ``(P,)`` under one world's schedule
    (``turn``, ``step`` ``(S,)``): segment ``s`` covers ``[s, s + 1) * horizon / S``; at its
    start the command blends linearly from the previous one over ``blend_cycles`` periods."""
    n_seg = turn.shape[0]
    seg_len = horizon / n_seg
    seg = jnp.clip(jnp.floor(times / seg_len).astype(jnp.int32), 0, n_seg - 1)
    prev = jnp.maximum(seg - 1, 0)
    alpha = jnp.clip((times - seg * seg_len) / (blend_cycles * params[PERIOD]), 0.0, 1.0)
    alpha = jnp.where(seg == 0, 1.0, alpha)
    tr = (1 - alpha) * turn[prev] + alpha * turn[seg]
    st = (1 - alpha) * step[prev] + alpha * step[seg]
    p = jnp.broadcast_to(params, (times.shape[0], params.shape[0]))
    return p.at[:, TURN].set(tr).at[:, STEP].multiply(st)


@struct.dataclass
class SteeredGaitProblem(GaitProblem):
    """Maximise forward progress without a fall while each world steers the gait (see the
    module's docstring); needs ``robust`` (the worlds carry the commands)."""

    steer: SteerConfig = struct.field(pytree_node=False, default_factory=SteerConfig)
    #: simulate the route walker's motor model (the scene model's position servos with the
    #: MJCF's force clamp, each target held for its control step) instead of the spec's (the
    #: NAO's: limits in the physics, interpolated targets): a gait chosen for one falls in
    #: the other
    walker_physics: bool = struct.field(pytree_node=False, default=True)

    @property
    def fall_cost(self) -> float:
        return 2.0 * self.horizon if self.steer.fall_cost is None else self.steer.fall_cost

    def steered_controls(self, solutions: jax.Array, worlds: Worlds) -> jax.Array:
        """Joint targets ``(R, m, n_steps, nu)``: every gait ``(m, dim)`` under every world's
        schedule (the engine's clock runs on, so a change never jumps the phase)."""
        turn, step = world_commands(worlds, self.steer)
        times = jnp.arange(self.n_steps, dtype=jnp.float32) * self.spec.control_dt
        heading = math.radians(self.direction_deg)

        def one(p, tr, st):
            pt = steered_params(p, tr, st, times, self.horizon, self.steer.blend_cycles)
            return jax.vmap(lambda q, t: joint_targets(q, t, self.spec, heading,
                                                       self.slope_deg, self.ik))(pt, times)

        per_ant = jax.vmap(one, in_axes=(0, None, None))
        return jax.vmap(per_ant, in_axes=(None, 0, 0))(solutions, turn, step)

    def steered_trace(self, solutions: jax.Array, worlds: Worlds) -> jax.Array:
        """Torso traces ``(m * R, n_steps + 1, 7)`` (rollout ``a * R + r``): each world's
        rollout of each gait under that world's commands, batched as one call."""
        controls = self.steered_controls(solutions, worlds)  # (R, m, T, nu)
        r = worlds.size
        # one world each, its own noise stream: vmapping the rollout keeps every ant in the
        # world its commands belong to (the plain problem runs every ant in every world)
        keys = jax.vmap(lambda i: jax.random.fold_in(worlds.noise_key, i))(jnp.arange(r))
        single = jax.tree.map(lambda x: x[:, None], worlds.replace(
            noise_key=keys[:, 0], noise_std=jnp.broadcast_to(worlds.noise_std, (r,))))
        single = single.replace(noise_key=keys, noise_std=single.noise_std[:, 0])
        trace = jax.vmap(self._controls_rollout)(controls, single)
        m = solutions.shape[0]
        return jnp.swapaxes(trace, 0, 1).reshape((m * r,) + trace.shape[2:])

    def _controls_rollout(self, controls: jax.Array, worlds: Worlds) -> jax.Array:
        """Torso traces of targets ``(m, T, nu)`` in ``worlds`` on this problem's backend."""
        spec_physics = None if not self.walker_physics else False
        if self.backend == "mjx":
            return mjx_rollout(controls, self.spec, self.slope_deg, self.accuracy, worlds,
                               False, impl=self.impl, limits=spec_physics,
                               interpolate=spec_physics)["trace"]
        return native_rollout_callback(controls, self.spec, self.slope_deg, self.accuracy,
                                       worlds, False, limits=spec_physics,
                                       interpolate=spec_physics)["trace"]

    def rollout(self, solutions: jax.Array, worlds: Worlds | None = None,
                quality: bool = False) -> dict[str, jax.Array]:
        """Per-world results ``(m, R)``: ``fitness`` (progress minus the fall cost),
        ``distance_m`` (forward progress in the torso's frame), ``speed_mps``, ``fell``,
        ``fall_time``, ``drift_deg`` (0: no desired direction) and ``turn_deg_s``."""
        if worlds is None:
            raise ProblemError("a steered gait problem needs randomised worlds: give it "
                               "robust=RobustConfig(...) (the worlds carry the commands)")
        if quality:
            raise ProblemError("a steered gait problem has no energy or quality metrics: "
                               "evaluate those on the plain gait problem")
        m, r = solutions.shape[0], worlds.size
        trace = self.steered_trace(solutions, worlds)
        summary = self.summarize(trace)
        fell = summary.fell | ~summary.finite
        fwd, _ = body_frame_speeds(trace, self.spec.control_dt, summary.fall_time)
        walked = jnp.where(summary.fell, summary.fall_time, summary.horizon)
        progress = jnp.where(summary.finite, fwd * walked, 0.0)
        turned = jnp.where(summary.finite, summary.turned_deg / jnp.maximum(walked, 1e-6), 0.0)
        res = {"fitness": jnp.where(fell, progress - self.fall_cost, progress),
               "distance_m": progress, "speed_mps": jnp.where(summary.finite, fwd, 0.0),
               "fell": fell, "fall_time": summary.fall_time,
               "drift_deg": jnp.zeros_like(progress), "turn_deg_s": turned}
        return {k: v.reshape((m, r)) for k, v in res.items()}


def make_steered_problem(robot: str = "nao", *, steer: SteerConfig | None = None,
                         walker_physics: bool = True, **kwargs: Any) -> SteeredGaitProblem:
    """A :class:`SteeredGaitProblem`: :func:`~eaco_jax.problems.gait.make_gait_problem`'s
    arguments (``robust`` required; no ``turn``, ``penalty`` or ``constrained``) plus the
    steering commands ``steer`` (default :class:`SteerConfig`); ``walker_physics`` (default)
    simulates the route walker's motor model, not the spec's."""
    for name in ("turn", "penalty", "constrained"):
        if kwargs.get(name):
            raise ProblemError(f"a steered gait problem takes no {name}: it walks forward "
                               "under the controller's commands")
    if kwargs.get("robust") is None:
        raise ProblemError("a steered gait problem needs randomised worlds: give it "
                           "robust=RobustConfig(...) (the worlds carry the commands)")
    steer = SteerConfig() if steer is None else steer
    if not isinstance(steer, SteerConfig):
        raise ProblemError(f"steer must be a SteerConfig, got {type(steer).__name__}")
    if not isinstance(walker_physics, bool | np.bool_):
        raise ProblemError(f"walker_physics must be True or False, got {walker_physics!r}")
    if kwargs.get("steering") is not None:
        raise ProblemError("a steered-command search walks the route walker's own commands: "
                           "drop steering")
    base = make_gait_problem(robot, **kwargs)
    if base.spec.gait != "biped":
        raise ProblemError(f"robot {base.spec.name!r} walks a {base.spec.gait} gait: steering "
                           "commands (turn_rate, step_length) exist for bipeds only")
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    return SteeredGaitProblem(**fields, steer=steer, walker_physics=bool(walker_physics))


__all__ = ["SteerConfig", "SteeredGaitProblem", "command_of", "make_steered_problem",
           "sample_commands", "steered_params", "world_commands"]
