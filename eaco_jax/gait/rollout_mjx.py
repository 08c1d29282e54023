"""Batched gait rollouts on MJX: a ``lax.scan`` over control steps of ``vmap(mjx.step)``.

Each control step sets the ant's precomputed position targets (the walk engine's output at
``t = k * control_dt``) and runs ``substeps`` ``mjx.step`` calls holding them. Only the torso
trace ``(T + 1, 6)`` per ant (root position and up axis after each control step, row 0 = start)
is kept, the same as the native backend returns; ``record=True`` also returns the joint
positions ``qpos`` after each control step (for plots).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from mujoco import mjx

from eaco_jax.gait.rollout_native import initial_state, native_model, substeps
from eaco_jax.gait.walk_engine import stand_pose
from eaco_jax.robots import RobotSpec


@functools.lru_cache(maxsize=16)
def mjx_model(spec: RobotSpec, slope_deg: float, accuracy: str) -> mjx.Model:
    """The MJX model for ``(robot, slope, accuracy)``, cached (same MjModel as native).

    Built with concrete arrays even when first called inside a jit trace: the cache outlives
    the trace, so a traced model would leak into the next one.
    """
    with jax.ensure_compile_time_eval():
        return mjx.put_model(native_model(spec, slope_deg, accuracy))


def root_trace(qpos: jax.Array) -> jax.Array:
    """``qpos`` (..., nq) -> torso position and up (z) axis ``(..., 6)`` from the free joint."""
    w, x, y, z = (qpos[..., i] for i in range(3, 7))
    up = jnp.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)
    return jnp.concatenate([qpos[..., :3], up], -1)


def mjx_trace(
    controls: jax.Array,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    record: bool = False,
):
    """Roll out control sequences ``controls`` ``(ants, T, nu)`` on MJX.

    The walk engine's targets are computed before the rollout (one batched op over ants and
    time), so the scan body holds nothing but physics: set ``ctrl``, ``substeps`` ``mjx.step``
    calls, keep the torso pose. Returns the torso trace ``(ants, T + 1, 6)`` (and ``qpos``
    ``(ants, T + 1, nq)`` when ``record``). Traceable: call it inside jit / scan.
    """
    model = native_model(spec, float(slope_deg), accuracy)
    k = substeps(spec, model)
    mm = mjx_model(spec, float(slope_deg), accuracy)
    qpos0 = jnp.asarray(initial_state(spec, model, slope_deg)[1 : 1 + model.nq], jnp.float32)
    ctrl0 = jnp.asarray(stand_pose(spec, slope_deg), jnp.float32)
    data = mjx.forward(mm, mjx.make_data(mm).replace(qpos=qpos0, ctrl=ctrl0))
    m = controls.shape[0]
    data = jax.tree.map(lambda a: jnp.broadcast_to(a, (m,) + a.shape), data)
    step = jax.vmap(lambda d: mjx.step(mm, d))

    def control_step(d, u):  # the whole colony: u (ants, nu)
        d = jax.lax.fori_loop(0, k, lambda _, dd: step(dd), d.replace(ctrl=u))
        return d, (root_trace(d.qpos), d.qpos if record else None)

    _, (trace, qpos) = jax.lax.scan(control_step, data,
                                    jnp.swapaxes(controls.astype(jnp.float32), 0, 1))
    start = jnp.broadcast_to(root_trace(qpos0), (1, m, 6))
    trace = jnp.swapaxes(jnp.concatenate([start, trace], 0), 0, 1)
    if record:
        qpos = jnp.concatenate([jnp.broadcast_to(qpos0, (1, m, qpos0.shape[0])), qpos], 0)
        return trace, jnp.swapaxes(qpos, 0, 1)
    return trace
