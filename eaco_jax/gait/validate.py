"""Validation of a stored gait: randomised trials, and export of a run that replays on plain MuJoCo.

:func:`evaluate_trials` simulates one gait in ``n`` randomised worlds (one batched call) drawn
from one of the run seed's three key streams (:data:`~eaco_jax.gait.worlds.STREAMS`): ``test``
by default (worlds nothing is chosen on), ``selection`` for choosing among finalists, or
``optimisation`` (the search's own stream, to measure overfitting). It summarises falls (with
n and the Clopper-Pearson 95 % interval), speed (mean and 95 % confidence half-width), cost of
transport and, for a robot with electrical motor data, the constraints of
:mod:`eaco_jax.gait.constraints` over the worlds. ``accurate=True``
re-runs them with MuJoCo's default solver settings (the spec's "accurate" solver: 2 ms
timestep, 100 iterations, 50 line-search iterations, tolerance 1e-8).

:func:`export_run` writes one nominal-world run as ``.npz``: ``ctrl`` (T x nu actuator inputs, one
row per control step), ``substeps``, ``control_dt``, ``qpos`` / ``qvel`` ((T + 1) x nq / nv at each
control step, row 0 the initial state) and ``model_xml`` (the MJCF the run was simulated with,
slope included). It replays with nothing but ``mujoco``::

    run = np.load("run.npz")
    m = mujoco.MjModel.from_xml_string(str(run["model_xml"]))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = run["qpos"][0], run["qvel"][0]
    for u in run["ctrl"]:
        d.ctrl[:] = u
        mujoco.mj_step(m, d, nstep=int(run["substeps"]))  # d.qpos == next row of run["qpos"]
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import jax
import mujoco
import numpy as np

from eaco_jax.errors import ProblemError
from eaco_jax.gait import constraints as gc
from eaco_jax.gait.motors import motor_model
from eaco_jax.gait.robot import model_xml
from eaco_jax.gait.rollout_native import initial_state, substeps
from eaco_jax.gait.stats import fall_rate
from eaco_jax.gait.worlds import STREAMS, RobustConfig, couple_controls, stream_key

TRIAL_STREAM = STREAMS["test"]
"""Key stream id of reported trials: the test stream."""


def evaluate_trials(problem: Any, params: Any, n: int = 100, seed: int = 0,
                    accurate: bool = False, config: RobustConfig | None = None,
                    stream: str = "test", batch: int = 0) -> dict[str, Any]:
    """Replay one gait in ``n`` randomised worlds (ranges: ``config``, else the problem's
    ``robust``, else :class:`RobustConfig` defaults) on the problem's backend and horizon,
    drawn from batch ``batch`` of ``stream`` of ``seed`` (the run's seed).

    Returns ``n``, ``falls``, ``fall_rate``, ``fall_rate_ci95`` (Clopper-Pearson),
    ``fall_trials`` (indices of the trials that fell: the same worlds replay with the same
    ``seed``, ``stream`` and ``batch``), ``speed_mps_mean``, ``speed_mps_ci95``
    (1.96 s / sqrt(n)), ``distance_m_mean``, ``cost_of_transport_mean`` (over trials that
    walked >= 1 cm), ``mean_power_w_mean`` (both NaN without a motor datasheet),
    ``constraints`` (robots with electrical data: :func:`eaco_jax.gait.constraints.table` over
    the worst world), ``seed``, ``stream``, ``batch``, ``accuracy``, ``backend``.
    """
    if not isinstance(n, int) or n < 1:
        raise ProblemError(f"trials must be a positive integer, got {n!r}")
    if stream not in STREAMS:
        raise ProblemError(f"stream must be one of {', '.join(STREAMS)}, got {stream!r}")
    quality = problem.spec.has_motors  # energy figures need a motor datasheet
    cfg = config or problem.robust or RobustConfig()
    prob = problem.replace(robust=cfg, accuracy="accurate" if accurate else problem.accuracy)
    x = prob.gait_row(params)
    worlds = prob.worlds(stream_key(int(seed), stream, int(batch)), n)
    res = jax.jit(lambda x, w: prob.rollout(x, w, quality=quality))(x, worlds)
    res = jax.tree.map(lambda v: np.asarray(v)[0], res)  # (n, ...)
    speed = res["speed_mps"].astype(np.float64)
    nan = np.full(n, np.nan)
    cot = res.get("cost_of_transport", nan)
    cot = cot[np.isfinite(cot)]
    out = {
        **fall_rate(int(np.sum(res["fell"])), n),
        "fall_trials": [int(i) for i in np.flatnonzero(res["fell"])],
        "speed_mps_mean": float(np.mean(speed)),
        "speed_mps_ci95": float(1.96 * np.std(speed, ddof=1) / math.sqrt(n)) if n > 1 else 0.0,
        "distance_m_mean": float(np.mean(res["distance_m"])),
        "cost_of_transport_mean": float(np.mean(cot)) if cot.size else float("nan"),
        "mean_power_w_mean": float(np.mean(res.get("mean_power_w", nan))),
        "turn_deg_s_mean": float(np.mean(res["turn_deg_s"])),
        "seed": int(seed),
        "stream": stream,
        "target_noise": float(cfg.target_noise),
        "batch": int(batch),
        "accuracy": prob.accuracy,
        "backend": prob.backend,
    }
    mm = motor_model(prob.spec)
    if mm is not None:
        vals = gc.values(jax.tree.map(lambda v: v[None], res), prob.turn)
        g = gc.normalised(vals, mm, prob.horizon, n)
        out["constraints"] = gc.table({k: np.asarray(v)[0] for k, v in vals.items()},
                                      np.asarray(g)[0], mm, prob.horizon, n)
    return out


def export_run(problem: Any, params: Any, path: str | Path,
               horizon: float | None = None) -> Path:
    """Simulate one gait (nominal world, MuJoCo's C engine, a model compiled from the exported
    MJCF text) and write the run to ``path`` (``.npz``, see the module docstring). The export
    is the position-servo model without the motor limits of
    :func:`eaco_jax.gait.motors.physics_limits` (their torque is computed per physics step from
    the state, which plain MuJoCo's open-loop ``ctrl`` cannot replay); ``limits_in_physics``
    in the file says so."""
    prob = problem if horizon is None else problem.replace(horizon=float(horizon))
    x = prob.gait_row(params)
    spec = prob.spec
    xml = model_xml(spec, slope_deg=prob.slope_deg, accuracy=prob.accuracy)
    model = mujoco.MjModel.from_xml_string(xml)
    k = substeps(spec, model)
    ctrl = np.asarray(couple_controls(jax.jit(prob.controls)(x), spec)[0], np.float64)
    state = initial_state(spec, model, prob.slope_deg)
    data = mujoco.MjData(model)
    data.qpos[:] = state[1 : 1 + model.nq]
    data.qvel[:] = state[1 + model.nq : 1 + model.nq + model.nv]
    qpos = [data.qpos.copy()]
    qvel = [data.qvel.copy()]
    for u in ctrl:
        data.ctrl[:] = u
        mujoco.mj_step(model, data, nstep=k)
        qpos.append(data.qpos.copy())
        qvel.append(data.qvel.copy())
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path, ctrl=ctrl, substeps=np.int64(k), control_dt=np.float64(spec.control_dt),
        qpos=np.array(qpos), qvel=np.array(qvel), model_xml=np.array(xml),
        timestep=np.float64(model.opt.timestep), params=np.asarray(x[0], np.float64),
        slope_deg=np.float64(prob.slope_deg), direction_deg=np.float64(prob.direction_deg),
        joint_names=np.array(spec.joint_names), limits_in_physics=np.bool_(False))
    return path


__all__ = ["TRIAL_STREAM", "evaluate_trials", "export_run"]
