"""Batched gait rollouts on MuJoCo's C engine, across all CPU threads (``mujoco.rollout``).

The controls are computed in JAX by the walk engine at the control rate, ``(ants, T, nu)``, and
held for ``substeps`` physics steps each. ``mujoco.rollout`` runs the ants in parallel on a
persistent thread pool (one ``MjData`` per thread); to keep memory small the horizon is cut into
time chunks (the state at the end of a chunk starts the next) and only the root pose after each
control step is kept. The result is the torso trace ``(ants, T + 1, 6)`` (position, up axis),
row 0 being the initial pose, exactly what :func:`eaco_jax.gait.fitness.summarize` reads.

:func:`native_trace` is the host function; :func:`native_trace_callback` wraps it with
``jax.pure_callback`` so a jitted colony loop (``lax.scan`` in :func:`eaco_jax.driver.minimize`) can
call it; batching over seeds is flattened into the ant axis.
"""

from __future__ import annotations

import functools
import os

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from eaco_jax.gait.walk_engine import stand_pose
from eaco_jax.robots import RobotSpec, load_model, stand_qpos

STATE_BYTES_PER_CALL = 64 * 2**20
"""Upper bound of the state buffer one ``mujoco.rollout`` call may fill (sets the chunk)."""


@functools.lru_cache(maxsize=16)
def native_model(spec: RobotSpec, slope_deg: float, accuracy: str) -> mujoco.MjModel:
    """The compiled model for ``(robot, slope, accuracy)``, cached."""
    return load_model(spec, slope_deg=slope_deg, accuracy=accuracy)


@functools.lru_cache(maxsize=16)
def _pool(nthread: int) -> mj_rollout.Rollout:
    return mj_rollout.Rollout(nthread=nthread)


def substeps(spec: RobotSpec, model: mujoco.MjModel) -> int:
    """Physics steps per control step (the control period must be a multiple of the timestep)."""
    n = spec.control_dt / model.opt.timestep
    if abs(n - round(n)) > 1e-6 or round(n) < 1:
        raise ValueError(
            f"control_dt {spec.control_dt} is not a multiple of timestep {model.opt.timestep}"
        )
    return int(round(n))


def initial_state(spec: RobotSpec, model: mujoco.MjModel, slope_deg: float) -> np.ndarray:
    """Full physics state of the standing keyframe, soles parallel to the (inclined) floor."""
    data = mujoco.MjData(model)
    qpos = np.array(stand_qpos(spec, model))
    pose = stand_pose(spec, slope_deg)
    for name, value in zip(spec.joint_names, pose, strict=True):
        qpos[model.joint(name).qposadr[0]] = value
    data.qpos[:] = qpos
    data.ctrl[:] = pose
    mujoco.mj_forward(model, data)
    spec_full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec_full))
    mujoco.mj_getState(model, data, state, spec_full)
    return state


def root_trace(qroot: np.ndarray) -> np.ndarray:
    """``(..., 7)`` root pose (xyz, wxyz) -> ``(..., 6)`` torso position and up (z) axis."""
    w, x, y, z = (qroot[..., i] for i in range(3, 7))
    up = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)
    return np.concatenate([qroot[..., :3], up], -1).astype(np.float32)


def native_trace(
    controls: np.ndarray,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    nthread: int | None = None,
    record_qpos: bool = False,
):
    """Roll out ``controls`` ``(ants, T, nu)`` (held per control step); torso trace
    ``(ants, T + 1, 6)``, plus the joint angles ``(ants, T + 1, nq)`` if ``record_qpos``."""
    controls = np.asarray(controls, np.float64)
    if controls.ndim != 3 or controls.shape[-1] != spec.nu:
        raise ValueError(f"controls must be (ants, T, {spec.nu}), got {controls.shape}")
    model = native_model(spec, float(slope_deg), accuracy)
    k = substeps(spec, model)
    ants, steps, _ = controls.shape
    nthread = nthread or os.cpu_count() or 1
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    state = np.tile(initial_state(spec, model, slope_deg), (ants, 1))
    nstate = state.shape[1]
    per_ctrl = max(1, STATE_BYTES_PER_CALL // (8 * nstate * k * max(ants, 1)))
    trace = np.empty((ants, steps + 1, 6), np.float32)
    trace[:, 0] = root_trace(state[:, 1:8])
    qpos_rec = np.empty((ants, steps + 1, model.nq), np.float32) if record_qpos else None
    if record_qpos:
        qpos_rec[:, 0] = state[:, 1 : 1 + model.nq]
    pool = _pool(nthread)
    for start in range(0, steps, per_ctrl):
        stop = min(steps, start + per_ctrl)
        ctrl = np.repeat(controls[:, start:stop], k, axis=1)
        out, _ = pool.rollout(model, datas, state, ctrl)
        sampled = out[:, k - 1 :: k]  # state after each control step
        trace[:, start + 1 : stop + 1] = root_trace(sampled[..., 1:8])
        if record_qpos:
            qpos_rec[:, start + 1 : stop + 1] = sampled[..., 1 : 1 + model.nq]
        state = np.ascontiguousarray(out[:, -1])
    if record_qpos:
        return trace, qpos_rec
    return trace


def native_trace_callback(
    controls: jax.Array, spec: RobotSpec, slope_deg: float = 0.0, accuracy: str = "fast"
) -> jax.Array:
    """:func:`native_trace` as a ``jax.pure_callback`` (usable under jit, vmap and scan)."""
    shape = jax.ShapeDtypeStruct(controls.shape[:-2] + (controls.shape[-2] + 1, 6), jnp.float32)

    def host(c: np.ndarray) -> np.ndarray:
        flat = np.asarray(c).reshape((-1,) + c.shape[-2:])
        out = native_trace(flat, spec, slope_deg, accuracy)
        return out.reshape(c.shape[:-2] + out.shape[-2:])

    return jax.pure_callback(host, shape, controls, vmap_method="broadcast_all")
