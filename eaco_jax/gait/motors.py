"""Electrical and thermal model of a robot's geared DC motors (NAO: nao.json ``motors``).

From the net joint torque ``tau`` and speed ``qdot`` of each physics step (the drive torque of
:mod:`eaco_jax.gait.quality`):

* motor current ``i = tau / (N k_t s) / eta`` when driving (``tau qdot >= 0``: the motor turns
  the load and the gears lose ``1 - eta``) and ``i = tau eta / (N k_t s)`` when back-driven
  (braking: the gear friction helps hold); ``N`` the reduction, ``k_t`` the torque constant,
  ``s`` the share of a motor (0.5 on each joint of a coupled pair);
* copper loss ``i^2 R`` (what heats the winding) and electrical power
  ``max(s i^2 R + p_shaft, 0)`` with the shaft power ``tau qdot / eta`` driving and
  ``tau qdot eta`` braking (NAO's boards do not recover energy, so a braking motor draws its
  copper loss less what the load returns, never less than 0);
* the current limit as a torque cap: ``|tau| <= N k_t s i_lim eta`` driving and
  ``N k_t s i_lim / eta`` braking; in the physics (:func:`limited_torque`, both backends, when
  the spec's ``motors.limits_in_physics`` is true) together with the voltage: while driving
  the joint gets at most ``eta`` times the torque-speed line ``stall - k_b |qdot|``;
* a two-node thermal model per motor: winding ``w`` and housing ``h`` above ambient,
  ``C_w dT_w/dt = P - (T_w - T_h) / R_wh``, ``C_h dT_h/dt = (T_w - T_h) / R_wh - T_h / R_ha``,
  with ``C_w = tau_w / R_wh`` and ``C_h = tau_h / R_ha``, integrated exactly for a loss held
  over each control step (modal form: two real negative eigenvalues);
* projection to continuous walking from the rollout's mean loss ``P`` (closed form; steady
  state ``T_w = P (R_wh + R_ha)``) plus a ripple bound: for any loss ``p(t)`` with mean ``P``
  the winding differs from the mean-loss response by at most ``2 M / C_w``, ``M`` the largest
  deviation of the cumulative loss from ``P t`` (the winding's impulse response is a sum of
  decaying exponentials with positive weights, starting at ``1 / C_w``; integration by parts).
  ``M`` is bounded from per-block loss energies (the cumulative loss is nondecreasing), so the
  bound holds for the rollout repeated end to end, the start-up from standing included.

Functions take ``xp`` (numpy on the host, jax.numpy in traced code) so both backends share
them.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np

KEYS = ("ratio", "share", "k_t", "r_ohm", "i_cont", "i_limit", "eta", "rth_wh", "rth_ha",
        "tau_w", "tau_h", "t_limit", "t_ambient", "t_max")
BLOCKS = 64
"""Blocks of the horizon whose loss energies bound the ripple (see the module docstring)."""
TEN_MINUTES = 600.0


class MotorModel(NamedTuple):
    """Per actuator ``(nu,)`` float64 arrays, fields :data:`KEYS` (see
    :func:`electrical_constants`)."""

    ratio: Any
    share: Any
    k_t: Any
    r_ohm: Any
    i_cont: Any
    i_limit: Any
    eta: Any
    rth_wh: Any
    rth_ha: Any
    tau_w: Any
    tau_h: Any
    t_limit: Any
    t_ambient: Any
    t_max: Any

    @property
    def kj(self):
        """Joint torque per ampere at 100 % gear efficiency (N m / A)."""
        return self.ratio * self.k_t * self.share

    @property
    def c_w(self):
        """Winding heat capacity (J / K)."""
        return self.tau_w / self.rth_wh


def electrical_constants(raw: dict[str, Any], joint_names) -> dict[str, list[float]] | None:
    """Per actuator constants from a spec's ``motors`` block, or None without one (no
    ``supply_voltage_v``). ``k_t`` = voltage / no-load speed, ``r_ohm`` = voltage k_t / stall
    torque, ``i_cont`` = nominal torque / k_t, ``i_limit`` = the spec's fraction of the stall
    current; winding-ambient resistance such that ``i_cont`` heats the winding to ``t_max`` at
    ``t_ambient``, split by ``rth_winding_share``."""
    motors = raw.get("motors", {})
    if "supply_voltage_v" not in motors:
        return None
    volt = float(motors["supply_voltage_v"])
    shared = {j for pair in raw.get("coupled_joints", []) for j in pair}
    out: dict[str, list[float]] = {k: [] for k in KEYS}
    for name in joint_names:
        key = name[1:] if name[:1] in "LR" and name[1:] in motors["joints"] else name
        mtype, ratio = motors["joints"][key]
        m = motors["types"][str(mtype)]
        k_t = volt / (m["no_load_rpm"] * 2.0 * math.pi / 60.0)
        r = volt * k_t / (m["stall_mNm"] * 1e-3)
        i_cont = m["nominal_mNm"] * 1e-3 / k_t
        rth = (m["max_winding_c"] - motors["ambient_c"]) / (i_cont**2 * r)
        vals = {
            "ratio": ratio, "share": 0.5 if name in shared else 1.0, "k_t": k_t, "r_ohm": r,
            "i_cont": i_cont, "i_limit": motors["current_limit_frac_of_stall"] * volt / r,
            "eta": motors["gear_efficiency"], "rth_wh": rth * m["rth_winding_share"],
            "rth_ha": rth * (1.0 - m["rth_winding_share"]), "tau_w": m["tau_winding_s"],
            "tau_h": m["tau_housing_s"], "t_limit": motors["firmware_limit_c"],
            "t_ambient": motors["ambient_c"], "t_max": m["max_winding_c"],
        }
        for k in KEYS:
            out[k].append(float(vals[k]))
    return out


def spec_json(spec) -> dict[str, Any]:
    """The robot's raw JSON spec (``spec.source``, else ``<name>.json`` beside its MJCF)."""
    path = getattr(spec, "source", "") or Path(spec.xml_path).with_name(f"{spec.name}.json")
    return json.loads(Path(path).read_text())


@functools.lru_cache(maxsize=8)
def physics_limits(spec) -> bool:
    """Whether the robot's rollouts apply the current limit and the gear efficiency in the
    physics (:func:`limited_torque`): the spec's ``motors.limits_in_physics`` (default off;
    never without electrical data)."""
    if motor_model(spec) is None:
        return False
    return bool(spec_json(spec)["motors"].get("limits_in_physics", False))


@functools.lru_cache(maxsize=8)
def interpolates_targets(spec) -> bool:
    """Whether the position targets reach the motors interpolated linearly between control
    steps (:func:`physics_targets`) instead of held: the spec's ``motors.interpolate_targets``
    (default off). NAO's DCM interpolates timed joint commands linearly at every DCM cycle
    (nao.json ``sources.targets``); held, a target that moves jumps once per control step and
    the stiff position loop answers each jump with a torque pulse."""
    return bool(spec_json(spec).get("motors", {}).get("interpolate_targets", False))


def physics_targets(u, u_next, k: int, interpolate: bool, xp=jnp):
    """Targets ``(..., k, nu)`` of the ``k`` physics steps of a control step whose target is
    ``u`` ``(..., nu)`` and whose successor's is ``u_next``: ``u + (j / k) (u_next - u)``,
    ``j = 0 .. k-1``, when ``interpolate``, else ``u`` held."""
    if not interpolate:
        return xp.broadcast_to(u[..., None, :], u.shape[:-1] + (k,) + u.shape[-1:])
    w = xp.asarray(np.arange(k) / k, u.dtype)[:, None]
    return u[..., None, :] + w * (u_next - u)[..., None, :]


@functools.lru_cache(maxsize=8)
def friction_share(spec) -> float:
    """The share of an actuated joint's damping that is friction, not back-EMF:
    ``f / (1 + f)`` with the spec's ``motors.frictionloss_fraction`` ``f`` (the damping is
    ``(1 + f) stall / no-load speed``). With the limits in the physics only this share stays
    in the model's damping; the back-EMF is part of :func:`limited_torque`."""
    f = float(spec_json(spec)["motors"].get("frictionloss_fraction", 0.0))
    return f / (1.0 + f)


@functools.lru_cache(maxsize=8)
def motor_model(spec) -> MotorModel | None:
    """The robot's :class:`MotorModel` (None for a robot without electrical data)."""
    consts = electrical_constants(spec_json(spec), spec.joint_names)
    if consts is None:
        return None
    return MotorModel(*(np.asarray(consts[k], np.float64) for k in KEYS))


# ----------------------------------------------------------------------------- electrical
def current(tau, qdot, mm: MotorModel, xp=jnp):
    """Motor current (A, signed like ``tau``): gear efficiency divides when driving and
    multiplies when back-driven."""
    driving = tau * qdot >= 0.0
    return tau / xp.asarray(mm.kj, tau.dtype) * xp.where(
        driving, 1.0 / xp.asarray(mm.eta, tau.dtype), xp.asarray(mm.eta, tau.dtype))


def copper_loss(i, mm: MotorModel, xp=jnp):
    """``i^2 R`` of one motor-equivalent (W): what heats the winding."""
    return i * i * xp.asarray(mm.r_ohm, i.dtype)


def electrical_power(tau, qdot, i, mm: MotorModel, xp=jnp):
    """Electrical power drawn by each actuator (W, >= 0): its share of ``i^2 R`` plus the shaft
    power (``tau qdot / eta`` driving, ``tau qdot eta`` braking)."""
    dt = tau.dtype
    eta = xp.asarray(mm.eta, dt)
    p = tau * qdot
    shaft = xp.where(p >= 0.0, p / eta, p * eta)
    return xp.maximum(xp.asarray(mm.share, dt) * copper_loss(i, mm, xp) + shaft, 0.0)


def torque_cap(tau, qdot, mm: MotorModel, xp=jnp):
    """``tau`` limited by the current limit: ``N k_t s i_lim eta`` driving, ``/ eta`` braking."""
    dt = tau.dtype
    base = xp.asarray(mm.kj * mm.i_limit, dt)
    eta = xp.asarray(mm.eta, dt)
    cap = xp.where(tau * qdot >= 0.0, base * eta, base / eta)
    return xp.clip(tau, -cap, cap)


def limited_torque(servo, qdot, stall, no_load_speed, mm: MotorModel, xp=jnp):
    """The joint torque a motor delivers through its gears in one physics step.

    ``servo`` = ``clip(kp (u - q), +-stall)`` is the voltage-saturated position loop in joint
    torque units; the back-EMF ``k_b qdot`` (``k_b = stall / no_load_speed``) makes it the
    torque at gear efficiency 1, ``t = servo - k_b qdot``, whose driving bound is the
    torque-speed line ``stall - k_b |qdot|`` at the supply voltage. The result is ``t`` clipped
    to ``+-cap``: driving (``t qdot >= 0``) ``cap = eta min(N k_t s i_lim, stall - k_b |qdot|)``
    (the gears lose ``1 - eta`` of what the motor gives, so the current needed,
    :func:`current`, reaches the limit or the voltage line exactly at the cap), braking
    ``cap = N k_t s i_lim / eta`` (friction in the gears helps the motor hold). The current
    limit is the motor board's, in amperes: it does not move with a world's stall tolerance."""
    dt = servo.dtype
    kb = stall / no_load_speed
    t = servo - kb * qdot
    lim = xp.asarray(mm.kj * mm.i_limit, dt)
    eta = xp.asarray(mm.eta, dt)
    line = xp.maximum(xp.minimum(lim, stall - kb * xp.abs(qdot)), 0.0)
    cap = xp.where(t * qdot >= 0.0, eta * line, lim / eta)
    return xp.clip(t, -cap, cap)


# ----------------------------------------------------------------------------- thermal
def thermal_matrix(mm: MotorModel) -> tuple[np.ndarray, np.ndarray]:
    """``A`` ``(nu, 2, 2)`` and ``b`` ``(nu, 2)`` of ``dx/dt = A x + b P``, ``x`` = (winding,
    housing) above ambient."""
    c_w, c_h = mm.tau_w / mm.rth_wh, mm.tau_h / mm.rth_ha
    g1, g2 = 1.0 / mm.rth_wh, 1.0 / mm.rth_ha
    a = np.stack([np.stack([-g1 / c_w, g1 / c_w], -1),
                  np.stack([g1 / c_h, -(g1 + g2) / c_h], -1)], -2)
    b = np.stack([1.0 / c_w, np.zeros_like(c_w)], -1)
    return a, b


class Modes(NamedTuple):
    """Modal form of the thermal model per actuator: eigenvalues ``lam`` (nu, 2), the winding
    row of the eigenvectors ``vw`` (nu, 2), input weights ``beta`` (nu, 2) (``V^-1 b``), and for a
    step ``dt``: ``mu = exp(lam dt)`` and ``gain = beta (mu - 1) / lam``."""

    lam: np.ndarray
    vw: np.ndarray
    beta: np.ndarray
    mu: np.ndarray
    gain: np.ndarray
    vmat: np.ndarray


def modes(mm: MotorModel, dt: float) -> Modes:
    """:class:`Modes` of the thermal model (float64, host)."""
    a, b = thermal_matrix(mm)
    tr = a[:, 0, 0] + a[:, 1, 1]
    det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    disc = np.sqrt(tr * tr / 4.0 - det)
    lam = np.stack([tr / 2.0 - disc, tr / 2.0 + disc], -1)  # fast, slow (both < 0)
    # eigenvector of lam: (a01, lam - a00)
    v = np.stack([np.broadcast_to(a[:, 0, 1:2], lam.shape), lam - a[:, 0, 0:1]], -2)  # (nu,2,2)
    beta = np.linalg.solve(v, b[..., None])[..., 0]
    mu = np.exp(lam * dt)
    return Modes(lam, v[:, 0, :], beta, mu, beta * (mu - 1.0) / lam, v)


def advance(z, losses, md: Modes, xp=jnp):
    """Modal state ``z`` ``(B, nu, 2)`` after control steps of held losses ``losses``
    ``(B, K, nu)`` (W), exact for a loss constant over each step."""
    k = losses.shape[-2]
    dt = z.dtype
    mu = xp.asarray(md.mu, dt)  # (nu, 2)
    powers = xp.asarray(md.mu[None] ** np.arange(k - 1, -1, -1)[:, None, None], dt)  # (K,nu,2)
    forced = xp.einsum("bkn,knm->bnm", losses.astype(dt), powers) * xp.asarray(md.gain, dt)
    return z * mu**k + forced


def temperatures(z, md: Modes, xp=jnp):
    """Winding and housing above ambient ``(..., nu, 2)`` from the modal state."""
    return xp.einsum("nij,...nj->...ni", xp.asarray(md.vmat, z.dtype), z)


def step_response(t, power, mm: MotorModel, xp=jnp):
    """Winding and housing above ambient ``(..., nu, 2)`` after ``t`` seconds at a constant
    loss ``power`` ``(..., nu)`` from ambient (closed form); ``t`` broadcasts to ``power``."""
    md = modes(mm, 1.0)
    power = xp.asarray(power)
    t = (xp.asarray(t) + xp.zeros_like(power))[..., None]
    z = xp.asarray(md.beta / -md.lam) * (1.0 - xp.exp(xp.asarray(md.lam) * t))
    return xp.einsum("nij,...nj->...ni", xp.asarray(md.vmat), z * power[..., None])


def steady_state(power, mm: MotorModel, xp=jnp):
    """Winding and housing above ambient at a constant loss: ``P (R_wh + R_ha)``, ``P R_ha``."""
    return xp.stack([power * xp.asarray(mm.rth_wh + mm.rth_ha), power * xp.asarray(mm.rth_ha)],
                    -1)


def ripple_bound(block_energy, seconds, power, mm: MotorModel, xp=jnp):
    """Bound (K) on the winding's deviation from the mean-loss response, ``2 M / C_w``, from the
    loss energy per block ``(B, NB, nu)`` over ``seconds`` ``(B,)`` of walking and the mean
    loss ``power`` ``(B, nu)``: within a block the cumulative loss is nondecreasing, so its
    deviation from ``P t`` lies between ``Q(a) - P b`` and ``Q(b) - P a``."""
    nb = block_energy.shape[-2]
    edges = seconds[..., None] * xp.arange(nb + 1) / nb  # (B, NB + 1)
    q = xp.concatenate([xp.zeros_like(block_energy[..., :1, :]),
                        xp.cumsum(block_energy, axis=-2)], axis=-2)  # (B, NB + 1, nu)
    lo = q[..., :-1, :] - power[..., None, :] * edges[..., 1:, None]
    hi = q[..., 1:, :] - power[..., None, :] * edges[..., :-1, None]
    m = xp.maximum(xp.max(xp.abs(lo), axis=-2), xp.max(xp.abs(hi), axis=-2))
    return 2.0 * m / xp.asarray(mm.c_w)


def minutes_to_limit(power, ripple, mm: MotorModel, xp=jnp, iters: int = 60):
    """Minutes of continuous walking from ambient until the winding (mean-loss response plus
    ``ripple``) reaches the firmware limit; ``inf`` when its steady state stays below. The
    winding's step response is increasing, so bisection on ``[0, 10^6 s]`` finds the crossing."""
    rise = xp.asarray(mm.t_limit - mm.t_ambient) - ripple
    steady = power * xp.asarray(mm.rth_wh + mm.rth_ha)
    never = steady <= rise
    lo, hi = xp.zeros_like(power), xp.full_like(power, 1e6)
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        hot = step_response(mid, power, mm, xp)[..., 0] >= rise
        lo, hi = xp.where(hot, lo, mid), xp.where(hot, mid, hi)
    t = xp.where(rise <= 0.0, 0.0, hi)
    return xp.where(never, xp.inf, t / 60.0)


__all__ = ["BLOCKS", "KEYS", "MotorModel", "advance", "copper_loss", "current",
           "electrical_constants", "electrical_power", "friction_share", "interpolates_targets",
           "limited_torque", "minutes_to_limit", "modes", "motor_model", "physics_limits",
           "physics_targets", "ripple_bound",
           "steady_state", "step_response", "temperatures", "torque_cap"]
