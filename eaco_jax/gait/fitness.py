"""The paper's gait fitness, as pure functions of a recorded torso trajectory.

Fitness (PAPER_NOTES §4): the distance covered in the desired walking direction during the
horizon. If the robot falls, the distance covered until the fall counts only when it exceeds
10 cm, else 0. No progress in the desired direction gives 0, and so does a drift of more than
45 degrees from the desired direction. Diverged (non-finite) physics gives 0, never NaN.

Turning gaits (``turn="left"`` / ``"right"``) are scored by the heading they turn instead: the
torso's yaw change in the asked sense (degrees, unwrapped) until the fall or the horizon; on a
fall it counts only above :data:`FALL_MIN_TURN_DEG`; turning the other way gives 0.

:func:`summarize` reduces a torso trace (position and up-axis at every control step) to a
:class:`GaitSummary`; :func:`gait_fitness` turns a summary into the fitness and the reported
quantities. Both are batched over any leading axes, so constructed cases test them directly.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
from flax import struct

FALL_MIN_DISTANCE = 0.10
"""On a fall, the distance until the fall counts only above this many metres."""
MAX_DRIFT_DEG = 45.0
"""Drift from the desired direction beyond which the fitness is 0."""
FALL_MIN_TURN_DEG = 15.0
"""On a fall, the heading turned until the fall counts only above this many degrees."""
TURNS = (None, "left", "right")


@struct.dataclass
class GaitSummary:
    """What fitness needs from one rollout (leading axes = ants)."""

    start_xy: jnp.ndarray  # (..., 2) torso position at t = 0
    end_xy: jnp.ndarray  # (..., 2) torso position at the fall, or at the horizon
    fell: jnp.ndarray  # (...,) bool
    fall_time: jnp.ndarray  # (...,) seconds (= horizon when it did not fall)
    finite: jnp.ndarray  # (...,) bool: the physics stayed finite
    horizon: jnp.ndarray  # (...,) seconds simulated
    turned_deg: jnp.ndarray  # (...,) heading change until the fall or the horizon (+ = left)


def is_down(pos, up, fall_height: float, fall_tilt_deg: float, slope_deg: float = 0.0, xp=jnp):
    """Whether a torso sample ``pos``/``up`` ``(..., 3)`` counts as fallen (the fall rule).

    ``xp`` is ``jax.numpy`` or ``numpy``: the rollouts test it inside their loops, on either side.
    """
    floor_z = pos[..., 0] * math.tan(math.radians(slope_deg))
    height = pos[..., 2] - floor_z
    return (height < fall_height) | (up[..., 2] < math.cos(math.radians(fall_tilt_deg)))


def summarize(
    pos: jnp.ndarray,
    up: jnp.ndarray,
    dt: float,
    fall_height: float,
    fall_tilt_deg: float,
    slope_deg: float = 0.0,
    yaw: jnp.ndarray | None = None,
) -> GaitSummary:
    """Summary of a torso trace ``pos``/``up`` ``(..., T, 3)`` (and heading ``yaw`` ``(..., T)``,
    rad) sampled every ``dt`` seconds.

    Row 0 is the start. The robot has fallen at the first row where the torso is lower than
    ``fall_height`` above the (possibly inclined) floor or its up axis is tilted more than
    ``fall_tilt_deg`` from the vertical.
    """
    n = pos.shape[-2]
    finite = jnp.all(jnp.isfinite(pos), axis=(-1, -2)) & jnp.all(jnp.isfinite(up), axis=(-1, -2))
    pos = jnp.nan_to_num(pos, nan=0.0, posinf=0.0, neginf=0.0)
    up = jnp.nan_to_num(up, nan=0.0, posinf=0.0, neginf=0.0)
    down = is_down(pos, up, fall_height, fall_tilt_deg, slope_deg)
    fell = jnp.any(down, axis=-1)
    first = jnp.where(fell, jnp.argmax(down, axis=-1), n - 1)
    end_xy = jnp.take_along_axis(pos[..., :2], first[..., None, None], axis=-2)[..., 0, :]
    horizon = jnp.full(fell.shape, (n - 1) * dt, jnp.float32)
    if yaw is None:
        turned = jnp.zeros(fell.shape, jnp.float32)
    else:  # unwrapped: sum of the wrapped steps up to the fall (or the horizon)
        yaw = jnp.nan_to_num(yaw, nan=0.0, posinf=0.0, neginf=0.0)
        step = jnp.diff(yaw, axis=-1)
        step = (step + jnp.pi) % (2 * jnp.pi) - jnp.pi
        upto = jnp.arange(n - 1) < first[..., None]
        turned = jnp.degrees(jnp.sum(jnp.where(upto, step, 0.0), axis=-1))
    return GaitSummary(
        start_xy=pos[..., 0, :2],
        end_xy=end_xy,
        fell=fell,
        fall_time=first.astype(jnp.float32) * dt,
        finite=finite,
        horizon=horizon,
        turned_deg=turned,
    )


def gait_fitness(summary: GaitSummary, direction_deg: float = 0.0,
                 turn: str | None = None) -> dict[str, jnp.ndarray]:
    """Fitness (to maximise) and ``distance_m``, ``speed_mps``, ``fell``, ``drift_deg``,
    ``turn_deg_s`` (heading change per second walked, + = left); ``turn`` scores the heading
    turned in that sense instead of the distance."""
    a = math.radians(direction_deg)
    u = jnp.array([math.cos(a), math.sin(a)], jnp.float32)
    disp = summary.end_xy - summary.start_xy
    along = disp @ u
    across = disp[..., 1] * u[0] - disp[..., 0] * u[1]
    drift = jnp.degrees(jnp.abs(jnp.arctan2(across, along)))
    ok = summary.finite & (along > 0.0) & (drift <= MAX_DRIFT_DEG)
    ok = ok & (~summary.fell | (along > FALL_MIN_DISTANCE))
    fitness = jnp.where(ok, along, 0.0)
    walked = jnp.where(summary.fell, summary.fall_time, summary.horizon)
    speed = jnp.where(summary.finite, along / jnp.maximum(walked, 1e-6), 0.0)
    if turn is not None:
        sense = {"left": 1.0, "right": -1.0}[turn]
        turned = sense * summary.turned_deg
        ok = summary.finite & (turned > 0.0) & (~summary.fell | (turned > FALL_MIN_TURN_DEG))
        fitness = jnp.where(ok, turned, 0.0)
    turn_rate = jnp.where(summary.finite, summary.turned_deg / jnp.maximum(walked, 1e-6), 0.0)
    return {
        "turn_deg_s": turn_rate,
        "fitness": fitness,
        "distance_m": jnp.where(summary.finite, along, 0.0),
        "speed_mps": speed,
        "fell": summary.fell | ~summary.finite,
        "drift_deg": jnp.where(summary.finite, drift, 180.0),
    }


AGGREGATES = ("mean", "worst", "cvar")


def aggregate(values: jnp.ndarray, how: str = "mean", alpha: float = 0.25) -> jnp.ndarray:
    """Reduce per-world values ``(..., R)`` to one per gait: the mean, the worst (min) or the
    CVaR-``alpha``, the mean of the worst ``ceil(alpha R)`` worlds (higher is better)."""
    if how == "mean":
        return jnp.mean(values, axis=-1)
    if how == "worst":
        return jnp.min(values, axis=-1)
    if how == "cvar":
        r = values.shape[-1]
        k = max(1, math.ceil(alpha * r))
        return jnp.mean(jnp.sort(values, axis=-1)[..., :k], axis=-1)
    raise ValueError(f"aggregate must be one of {', '.join(AGGREGATES)}, got {how!r}")
