"""A long walk with the motors' temperatures integrated along it (``eaco gait-eval --horizon 600``).

One stored gait walks ``horizon`` seconds, in the nominal world (one rollout) or in ``n``
randomised worlds of a key stream (one batched rollout: MJX on a GPU, native MuJoCo on the
CPU). The two-node thermal model of :mod:`eaco_jax.gait.motors` runs from ambient (25 C) on the
copper loss of every control step, inside the rollout: the winding and housing temperatures
are sampled every ``sample_s`` seconds (a decimated trace; nothing per physics step is kept)
and the first control step at which each winding reaches the firmware limit is recorded.

The record (:func:`thermal_walk`) holds, per joint, the hottest world's winding and housing
temperature at the end and its trace, the steady state of this walk repeated (the walk's mean
copper loss times the winding-ambient thermal resistance), the peak current
against the current limit and when (and in how many worlds) the firmware limit was reached;
per gait, the falls with the Clopper-Pearson 95 % interval, speed, foot slip per metre and
drift over every world, and (``walking_worlds``) slip, drift and the hottest winding over the
worlds that did not fall.
"""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait.fitness import gait_fitness
from eaco_jax.gait.rollout_mjx import mjx_rollout
from eaco_jax.gait.rollout_native import native_model, native_rollout, native_rollout_callback
from eaco_jax.gait.stats import fall_rate
from eaco_jax.gait.worlds import RobustConfig, couple_controls, stream_key

LEG_ROLES = ("HipYawPitch", "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll")
"""NAO leg joints (without the L/R prefix): the rows of the summary table."""


def thermal_walk(problem: Any, params: Any, n: int = 0, seed: int = 0, stream: str = "test",
                 sample_s: float = 1.0, config: RobustConfig | None = None) -> dict[str, Any]:
    """Walk one gait ``problem.horizon`` seconds with the thermal model integrated (see the
    module docstring); ``n`` > 0: in ``n`` worlds of ``stream`` of ``seed`` (ranges:
    ``config``, else the defaults), batch 0; else in the nominal world."""
    spec = problem.spec
    mm = mo.motor_model(spec)
    if mm is None:
        raise ValueError(f"robot {spec.name} has no electrical motor data: no thermal walk")
    every = max(1, int(round(sample_s / spec.control_dt)))
    x = problem.gait_row(params)
    controls, steer = problem.controls_and_steer(x)
    worlds = None
    if n:
        cfg = config or RobustConfig(seed=int(seed))
        worlds = problem.replace(robust=cfg).worlds(stream_key(int(seed), stream, 0), int(n))
    out = _rollout(problem, controls, worlds, every, steer)
    summary = problem.summarize(out["trace"])
    res = gait_fitness(summary, problem.direction_deg, problem.turn)
    model = native_model(spec, float(problem.slope_deg), problem.accuracy)
    r = 1 if worlds is None else worlds.size
    mass = float(np.sum(model.body_mass))
    nominal = jnp.asarray(spec.nominal_torque, jnp.float32)
    if worlds is not None:
        mass = jnp.sum(jnp.asarray(model.body_mass) * worlds.mass_scale, -1)
        nominal = nominal * worlds.stall_scale
    q = ql.finalize(jax.tree.map(jnp.asarray, out["acc"]), res["distance_m"], mass,
                    float(model.opt.timestep), nominal, mm)
    rec = _record(problem, q, res, r, every, stream if n else "nominal", seed, mm)
    rec = rec | {"legs": leg_table(rec)}
    if worlds is not None:
        rec["target_noise"] = float(cfg.target_noise)
    return rec


def _rollout(problem: Any, controls: jax.Array, worlds, every: int, steer) -> dict:
    spec = problem.spec
    if problem.backend == "mjx":
        run = jax.jit(lambda c: mjx_rollout(c, spec, problem.slope_deg, problem.accuracy,
                                            worlds, quality=True, impl=problem.impl,
                                            trace_every=every, steer=steer))
        return jax.device_get(run(controls))
    if worlds is None:
        return native_rollout(couple_controls(np.asarray(controls), spec, xp=np), spec,
                              problem.slope_deg, problem.accuracy, quality=True,
                              trace_every=every, steer=steer)
    return jax.device_get(native_rollout_callback(controls, spec, problem.slope_deg,
                                                  problem.accuracy, worlds, quality=True,
                                                  trace_every=every, steer=steer))


def _f(v: Any) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _record(problem, q: dict, res: dict, r: int, every: int, stream: str, seed: int,
            mm: mo.MotorModel) -> dict[str, Any]:
    spec = problem.spec
    names = spec.joint_names
    dt = spec.control_dt
    fell = np.asarray(res["fell"]).reshape(r)
    distance = np.asarray(res["distance_m"]).reshape(r)
    speed = np.asarray(res["speed_mps"]).reshape(r)
    walked = np.maximum(distance, 0.10)
    slip = np.asarray(q["foot_slip_m"]).reshape(r) / walked
    drift = np.asarray(res["drift_deg"]).reshape(r)
    wind = np.asarray(q["winding_trace_c"]).reshape(r, -1, len(names))
    house = np.asarray(q["housing_trace_c"]).reshape(r, -1, len(names))
    hot = np.asarray(q["limit_step"]).reshape(r, len(names))
    end_w = np.asarray(q["winding_end_c"]).reshape(r, len(names))
    end_h = np.asarray(q["housing_end_c"]).reshape(r, len(names))
    # steady state of this walk repeated: the mean copper loss through both resistances (no
    # ripple bound: over a long walk the mean loss is the walk's own)
    loss = np.asarray(q["copper_loss_w"]).reshape(r, len(names))
    steady = mm.t_ambient + loss * (mm.rth_wh + mm.rth_ha)
    peak_i = np.asarray(q["peak_current_frac"]).reshape(r, len(names))
    limit = float(np.min(mm.t_limit))
    joints = {}
    for j, name in enumerate(names):
        reached = hot[:, j] >= 0
        joints[name] = {
            "winding_end_c": float(end_w[:, j].max()),
            "housing_end_c": float(end_h[:, j].max()),
            "winding_steady_c": _f(steady[:, j].max()),
            "firmware_limit_c": float(mm.t_limit[j]),
            "peak_current_frac": float(peak_i[:, j].max()),
            "limit_reached_s": (float((hot[reached, j].min() + 1) * dt) if reached.any()
                                else None),
            "worlds_reaching_limit": int(reached.sum()),
        }
    first = [v["limit_reached_s"] for v in joints.values() if v["limit_reached_s"] is not None]
    walk = ~fell  # a fallen robot's slip, drift and heat say nothing about the gait
    walking = None if not walk.any() else {
        "worlds": int(walk.sum()), "slip_per_m_max": float(slip[walk].max()),
        "drift_deg_max": float(drift[walk].max()),
        "winding_end_c_max": float(end_w[walk].max()),
        "hottest_joint": names[int(end_w[walk].max(axis=0).argmax())]}
    t = (np.arange(wind.shape[1]) + 1) * every * dt
    return {
        "horizon_s": float(problem.horizon), "stream": stream, "seed": int(seed),
        "worlds": int(r), "backend": problem.backend, "sample_s": every * dt,
        "ambient_c": float(mm.t_ambient[0]), "firmware_limit_c": limit,
        "limit_reached": bool(first), "first_limit_s": min(first) if first else None,
        "worlds_reaching_limit": int(np.sum(np.any(hot >= 0, axis=1))),
        **fall_rate(int(fell.sum()), r),
        "speed_mps_mean": float(speed.mean()),
        "slip_per_m_max": float(slip.max()), "drift_deg_max": float(drift.max()),
        "peak_current_max_frac": float(peak_i.max()),
        "walking_worlds": walking,
        "joints": joints,
        "trace": {"t_s": [round(float(v), 6) for v in t],
                  "winding_c": {n: [round(float(v), 3) for v in wind[:, :, j].max(0)]
                                for j, n in enumerate(names)},
                  "housing_c": {n: [round(float(v), 3) for v in house[:, :, j].max(0)]
                                for j, n in enumerate(names)}},
    }


def leg_table(rec: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per leg joint (the hotter of left and right): winding after the walk and at steady
    state against the firmware limit, peak current against the current limit."""
    out = {}
    for role in LEG_ROLES:
        rows = [v for k, v in rec["joints"].items() if k.endswith(role)]
        if not rows:
            continue
        steady = [r["winding_steady_c"] for r in rows]
        out[role] = {
            "winding_end_c": max(r["winding_end_c"] for r in rows),
            "winding_steady_c": None if None in steady else max(steady),
            "firmware_limit_c": rows[0]["firmware_limit_c"],
            "peak_current_frac": max(r["peak_current_frac"] for r in rows),
            "limit_reached_s": min((r["limit_reached_s"] for r in rows
                                    if r["limit_reached_s"] is not None), default=None),
        }
    return out


__all__ = ["LEG_ROLES", "leg_table", "thermal_walk"]
