"""The constraints of a constrained gait search, as pure functions of per-world rollout results.

A constrained gait problem (``make_gait_problem(..., constrained=True)``) maximises speed
subject to inequality constraints ``g <= 0``, each computed from the same batched rollout over
the R randomised worlds and normalised by its own limit, so one unit of violation means "the
limit exceeded by its own size" for every constraint (fall: every world fell):

* ``endurance``: no joint's winding reaches the firmware limit within ten minutes of continuous
  walking from ambient (:mod:`eaco_jax.gait.motors`: the mean-loss response plus the ripple
  bound, ``winding_10min_c``). ``g = max over worlds and joints of (T_10min - T_limit) /
  (T_limit - T_ambient)``. The winding's step response increases with time, so ``g <= 0`` is
  the same as an endurance of at least ten minutes, but ``g`` keeps growing with the heat where
  the endurance in minutes saturates at 0.
* ``current``: the peak motor current within the current limit, ``g = max(peak / limit) - 1``
  (the limit caps torque braking as driving, :func:`~eaco_jax.gait.motors.torque_cap`). With
  the limits in the physics (:func:`~eaco_jax.gait.motors.physics_limits`) the current stops
  at the limit, so this holds by construction up to float32 rounding
  (:data:`CURRENT_ROUNDING` of slack).
* ``slip``: foot slip while in contact per metre walked at most :data:`SLIP_PER_M`,
  ``g = (slip / max(d, 0.1 m) - 0.05) / 0.05`` with ``d`` the distance walked in the desired
  direction (the floor keeps a gait that barely moves from dividing by ~0).
* ``drift``: the drift from the desired direction at most :func:`drift_limit_deg` of the
  horizon, ``g = (drift - limit) / limit``. A walk that curves at a constant rate drifts in
  proportion to time (the chord of an arc turns half as far as the heading), so the 10 degree
  limit over 20 s is scaled linearly for a shorter horizon and held at 10 degrees beyond 20 s;
  below 5 s it stays at 2.5 degrees, as the start-up and the torso's sideways sway within a
  step move the chord's direction by that order over the first metre or two.
  Turning gaits (``turn``) have no drift constraint: turning is their objective.
* ``falls``: no fall in any world, ``g = fallen worlds / R``.

Every constraint but ``falls`` takes the worst world (it must hold in each world); a
non-finite value (diverged physics) counts as :data:`NONFINITE_VIOLATION`.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from eaco_jax.gait.stats import fall_rate

#: the constraints in the order of the violation vector (turning gaits drop ``drift``)
CONSTRAINTS = ("endurance", "current", "slip", "drift", "falls")
ENDURANCE_MIN = 10.0
"""Minutes of continuous walking from ambient before any winding may reach the firmware limit
(the motor model's ``winding_10min_c`` is the winding after exactly this long)."""
SLIP_PER_M = 0.05
"""Largest foot slip while in contact per metre walked (m / m)."""
SLIP_MIN_DISTANCE = 0.10
"""Slip is divided by at least this many metres (a gait that barely moves)."""
DRIFT_DEG = 10.0
DRIFT_HORIZON = 20.0
"""Largest drift from the desired direction, :data:`DRIFT_DEG` over :data:`DRIFT_HORIZON` s."""
DRIFT_MIN_HORIZON = 5.0
"""Below this horizon the drift limit stays at its value for this horizon."""
NONFINITE_VIOLATION = 100.0
"""Normalised violation of a constraint whose value is not finite (diverged physics)."""
CURRENT_ROUNDING = 1e-4
"""Slack on the current constraint: a current held at the limit reads 1 + ~1e-7 in float32."""
UNITS = {"endurance": "C", "current": "x limit", "slip": "m/m", "drift": "deg",
         "falls": "worlds"}


def names(turn: str | None) -> tuple[str, ...]:
    """The constraints of a gait problem (walking: all five; any other ``turn``, a turning gait's
    or the gait library's whose yaw rate is asked for: without ``drift``)."""
    return tuple(c for c in CONSTRAINTS if turn is None or c != "drift")


def drift_limit_deg(horizon: float) -> float:
    """The drift limit for a horizon: 10 degrees over 20 s, linear down to 2.5 degrees at 5 s,
    constant outside."""
    h = min(max(float(horizon), DRIFT_MIN_HORIZON), DRIFT_HORIZON)
    return DRIFT_DEG * h / DRIFT_HORIZON


def limits(mm: Any, horizon: float) -> dict[str, float]:
    """Each constraint's limit in its own unit (``endurance``: the firmware limit in C, the
    lowest over joints)."""
    return {"endurance": float(np.min(mm.t_limit)), "current": 1.0 + CURRENT_ROUNDING,
            "slip": SLIP_PER_M,
            "drift": drift_limit_deg(horizon), "falls": 0.0}


def values(res: dict[str, Any], turn: str | None = None) -> dict[str, jnp.ndarray]:
    """Each constraint's value per gait ``(m,)`` from per-world results ``(m, R[, nu])``
    (:meth:`~eaco_jax.problems.gait.GaitProblem.rollout` with ``quality``): the hottest winding
    after ten minutes (C), peak current / limit, slip per metre, drift (deg) over the worst
    world, and the number of worlds that fell."""
    hot = jnp.max(res["winding_10min_c"], axis=(-1, -2))
    current = jnp.max(res["peak_current_max_frac"], axis=-1)
    walked = jnp.maximum(res["distance_m"], SLIP_MIN_DISTANCE)
    slip = jnp.max(res["foot_slip_m"] / walked, axis=-1)
    out = {"endurance": hot, "current": current, "slip": slip,
           "drift": jnp.max(res["drift_deg"], axis=-1),
           "falls": jnp.sum(res["fell"].astype(jnp.float32), axis=-1)}
    return {k: out[k] for k in names(turn)}


def normalised(vals: dict[str, jnp.ndarray], mm: Any, horizon: float,
               worlds: int) -> jnp.ndarray:
    """The normalised constraints ``g`` ``(m, p)`` (feasible where every entry is <= 0), in
    the order of :data:`CONSTRAINTS` (see the module docstring)."""
    lim = limits(mm, horizon)
    rise = float(np.min(mm.t_limit - mm.t_ambient))
    scale = {"endurance": rise, "current": 1.0, "slip": SLIP_PER_M,
             "drift": max(lim["drift"], 1e-6), "falls": float(worlds)}
    g = jnp.stack([(jnp.asarray(vals[k], jnp.float32) - lim[k]) / scale[k]
                   for k in _ordered(vals)], axis=-1)
    return jnp.where(jnp.isfinite(g), g, NONFINITE_VIOLATION)


def _ordered(vals: dict[str, Any]) -> list[str]:
    """The constraints present in ``vals`` in :data:`CONSTRAINTS` order (a dict passed through
    ``jax.jit`` comes back with its keys sorted)."""
    return [k for k in CONSTRAINTS if k in vals]


#: the constraints a search margin tightens: those whose worst of R worlds grows with R
#: (a margin on ``current`` or ``falls`` would mean nothing: the physics holds the current at
#: its limit, and a fall is a count)
MARGIN_CONSTRAINTS = ("endurance", "slip", "drift")


def with_margin(g: jnp.ndarray, margin: float, present: tuple[str, ...]) -> jnp.ndarray:
    """Normalised constraints ``g`` ``(m, p)`` (columns ``present``, in :data:`CONSTRAINTS`
    order) tightened by ``margin`` on :data:`MARGIN_CONSTRAINTS`: they hold only with
    ``margin`` of their scale to spare (``0.1``: 5 C below the firmware limit, 0.005 m/m of
    slip, 1 degree of drift over 20 s)."""
    if margin == 0.0:
        return g
    add = jnp.asarray([margin if k in MARGIN_CONSTRAINTS else 0.0
                       for k in CONSTRAINTS if k in present], g.dtype)
    return g + add


def violation(g: jnp.ndarray) -> jnp.ndarray:
    """Total violation ``(m,)`` of normalised constraints ``(m, p)``: sum of ``max(g, 0)``, the
    constrained problems' rule (:func:`eaco_jax.problems.constrained.violation_of`)."""
    return jnp.sum(jnp.maximum(g, 0.0), axis=-1)


def table(vals: dict[str, Any], g: Any, mm: Any, horizon: float,
          worlds: int) -> dict[str, dict[str, Any]]:
    """JSON-ready report of one gait in ``worlds`` worlds: per constraint its value, limit, unit,
    margin (limit minus value, in the value's unit; >= 0 holds), normalised ``g`` and whether it
    holds; ``falls`` also with its n and the Clopper-Pearson 95% interval of the fall rate."""
    lim = limits(mm, horizon)
    g = np.asarray(g, np.float64).reshape(-1)
    out = {}
    for j, k in enumerate(_ordered(vals)):
        value = float(np.asarray(vals[k]).reshape(-1)[0])
        out[k] = {"value": value, "limit": lim[k], "unit": UNITS[k],
                  "margin": lim[k] - value, "g": float(g[j]), "holds": bool(g[j] <= 0.0)}
    if "falls" in out:
        out["falls"].update(fall_rate(round(out["falls"]["value"]), worlds))
    return out


__all__ = ["CONSTRAINTS", "DRIFT_DEG", "ENDURANCE_MIN", "SLIP_PER_M", "drift_limit_deg",
           "limits", "names", "normalised", "table", "values", "violation"]
