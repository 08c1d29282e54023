"""Heading feedback for a walking gait: the walk engine's turn rate driven by the torso's pose.

An open-loop gait walks where its joint errors take it: a world's target noise, masses and
motor tolerances turn it a few degrees over twenty seconds, and the drift constraint of
:mod:`eaco_jax.gait.constraints` binds. A real NAO walk engine closes that loop with the
torso's inertial unit and its odometry. :class:`Steering` does the same inside the gait
rollouts of both backends, at every control step, from the torso pose at the step's start:

* the error ``e = -yaw - atan(cross / lookahead)`` [rad]: the heading back to the desired
  direction (the torso starts facing it, yaw 0) plus the turn toward the desired line through
  the start (``cross``: metres left of it); ``lookahead = inf`` holds the heading only;
  with ``track_turn`` the heading to hold turns at the gait's own commanded turn rate ``w``
  (``e = wrap(w t - yaw)``, ``t`` the control step's start): a turning gait (a gait-library
  cell) then turns at the rate it asks for, not wherever its joint errors take it;
* a first-order low-pass over ``tau`` seconds (``z += (e - z) dt / (tau + dt)``), which keeps
  the torso's sway within a step out of the command;
* the turn correction ``c = clip(gain z, -max_rate, max_rate)`` [rad/s].

The joint targets become ``u(t) + c du/d(turn_rate)(t)``: the walk engine's targets at turn
rate ``turn_rate + c``, to first order (:func:`turn_sensitivity`; the foot yaw is linear in the
turn rate, the leg IK is not; at the clamp the difference from the engine's targets stays
below a quarter of one 12-bit encoder count, which tests/test_heading_feedback.py checks on the
margin-searched constrained NAO gait). A world's
latency delays the correction with the command: a world ``L >= 1`` control steps late uses the
correction of the step before (one step of memory, which covers the default latency range
``0..1``). With targets interpolated between control steps the next step's target carries this
step's correction, so the command stays continuous.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ProblemError

#: the claim (experiments/claims.toml) behind the defaults of :class:`Steering`: the ablation
#: that read gain 1 and the heading alone off the selection worlds of an earlier search
DEFAULTS_CLAIM = "steer-abl-gain1-feasible"


@dataclasses.dataclass(frozen=True)
class Steering:
    """The heading controller's settings (see the module docstring; the defaults:
    :data:`DEFAULTS_CLAIM`)."""

    gain: float = 1.0  # rad/s of turn per rad of error
    lookahead: float = math.inf  # m; inf: hold the heading only
    max_rate: float = 0.3  # clamp of the correction [rad/s] (the engine's turn_rate box)
    tau: float = 0.5  # low-pass time constant [s]
    track_turn: bool = False  # hold a heading that turns at the gait's commanded turn rate

    def __post_init__(self) -> None:
        for name in ("gain", "max_rate", "tau"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ProblemError(f"steering {name} must be a finite number >= 0, got {v!r}")
        v = self.lookahead
        if not (isinstance(v, int | float) and not math.isnan(v) and v > 0):
            raise ProblemError(f"steering lookahead must be > 0 (inf: heading only), got {v!r}")
        if not isinstance(self.track_turn, bool):
            raise ProblemError(f"steering track_turn must be true or false, got "
                               f"{self.track_turn!r}")
        if self.track_turn and not math.isinf(self.lookahead):
            raise ProblemError("steering track_turn holds a turning heading, not a line: "
                               "drop lookahead")

    def record(self) -> dict[str, Any]:
        """JSON-ready settings (``lookahead`` ``None`` for infinity)."""
        d = dataclasses.asdict(self)
        d["lookahead"] = None if math.isinf(self.lookahead) else self.lookahead
        if not self.track_turn:  # a heading-holding record reads as it did before track_turn
            del d["track_turn"]
        return d

    @classmethod
    def from_record(cls, d: dict[str, Any] | None) -> Steering | None:
        """The settings of :meth:`record` (``None`` stays ``None``: no feedback)."""
        if d is None:
            return None
        keys = {"gain", "lookahead", "max_rate", "tau", "track_turn"}
        if not isinstance(d, dict) or set(d) - keys:
            raise ProblemError(f"steering must be a mapping of gain, lookahead, max_rate, tau "
                               f"(and track_turn); got {d!r}")
        d = dict(d)
        if d.get("lookahead", 0.0) is None:
            d["lookahead"] = math.inf
        track = d.pop("track_turn", False)  # records before track_turn existed lack it
        if not isinstance(track, bool):
            raise ProblemError(f"steering track_turn must be true or false, got {track!r}")
        return cls(**{k: float(v) for k, v in d.items()}, track_turn=track)


class SteerInputs(NamedTuple):
    """What a rollout needs to steer: the targets' sensitivity to the turn rate ``(A, T, nu)``
    (joint coupling applied), the settings, the desired direction [rad] and, with
    ``steering.track_turn``, each gait's commanded turn rate ``(A,)`` [rad/s]."""

    dcontrols: Any
    steering: Steering
    direction: float
    rates: Any = None


class SteerState(NamedTuple):
    """Per rollout ``(B,)``: the filtered error and the correction of the step before."""

    z: Any
    c_prev: Any


def turn_sensitivity(controls_fn, solutions: jax.Array,
                     turn_index: int) -> tuple[jax.Array, jax.Array]:
    """``controls_fn(solutions)`` and its derivative with respect to the turn rate, both
    ``(A, T, nu)``, in one forward-mode pass."""
    tangent = jnp.zeros_like(solutions).at[:, turn_index].set(1.0)
    return jax.jvp(controls_fn, (solutions,), (tangent,))


def start_state(nb: int, xp=jnp) -> SteerState:
    z = xp.zeros((nb,), xp.float32)
    return SteerState(z, z)


def _wrap(a, xp):
    return xp.arctan2(xp.sin(a), xp.cos(a))


def update(state: SteerState, trace_row, start_xy, direction: float, cfg: Steering,
           dt: float, xp=jnp, ref=None):
    """One control step of the controller from the torso row ``(B, 7)`` (position, up, yaw)
    and the start position ``(B, 2)``. Returns the new state (which keeps this correction as the
    next step's ``c_prev``) and this step's correction ``(B,)`` [rad/s]; a world with latency
    applies the previous one instead (:func:`delayed`). ``ref`` ``(B,)`` [rad]: the heading to
    hold (``track_turn``: :func:`turn_reference`; None: the start's, 0)."""
    ux, uy = math.cos(direction), math.sin(direction)
    dx = trace_row[:, 0] - start_xy[:, 0]
    dy = trace_row[:, 1] - start_xy[:, 1]
    cross = dy * ux - dx * uy
    yaw = trace_row[:, 6]
    if ref is not None:  # in the trace's precision, so a zero reference is heading hold exactly
        yaw = yaw - xp.asarray(ref, dtype=yaw.dtype)
    err = -_wrap(yaw, xp)
    if not math.isinf(cfg.lookahead):
        err = err - xp.arctan(cross / cfg.lookahead)
    err = _wrap(err, xp)
    z = state.z + (err - state.z) * (dt / (cfg.tau + dt))
    c = xp.clip(cfg.gain * z, -cfg.max_rate, cfg.max_rate).astype(xp.float32)
    return SteerState(z.astype(xp.float32), c), c


def turn_reference(rates, step: int | Any, dt: float):
    """The heading ``(B,)`` [rad] a ``track_turn`` controller holds at control step ``step``:
    the commanded turn rates ``(B,)`` [rad/s] times the step's start time."""
    return rates * (step * dt)


def delayed(c, c_prev, latency):
    """The correction a world with ``latency`` control steps (``(B,)`` int) applies now."""
    return np.where(latency >= 1, c_prev, c) if isinstance(c, np.ndarray) else jnp.where(
        latency >= 1, c_prev, c)
