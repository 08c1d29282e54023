"""Batched gait rollouts on MJX: ``vmap`` over ants of a ``lax.scan`` over control steps.

Each control step computes the walk engine's position targets for the ant's parameters at
``t = k * control_dt`` and runs ``substeps`` ``mjx.step`` calls holding them. Only the torso
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
from eaco_jax.gait.walk_engine import joint_targets, stand_pose
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
    params: jax.Array,
    n_steps: int,
    spec: RobotSpec,
    slope_deg: float = 0.0,
    heading: float = 0.0,
    accuracy: str = "fast",
    record: bool = False,
):
    """Roll out gaits ``params`` ``(ants, d)`` for ``n_steps`` control steps on MJX.

    Returns the torso trace ``(ants, n_steps + 1, 6)`` (and ``qpos`` ``(ants, n_steps + 1, nq)``
    when ``record``). Traceable: call it inside jit / scan.
    """
    model = native_model(spec, float(slope_deg), accuracy)
    k = substeps(spec, model)
    mm = mjx_model(spec, float(slope_deg), accuracy)
    qpos0 = jnp.asarray(initial_state(spec, model, slope_deg)[1 : 1 + model.nq], jnp.float32)
    ctrl0 = jnp.asarray(stand_pose(spec, slope_deg), jnp.float32)

    def one(p: jax.Array):
        data = mjx.make_data(mm).replace(qpos=qpos0, ctrl=ctrl0)
        data = mjx.forward(mm, data)

        def control_step(d, i):
            u = joint_targets(p, i.astype(jnp.float32) * spec.control_dt, spec, heading,
                              slope_deg)
            d = d.replace(ctrl=u)
            d = jax.lax.fori_loop(0, k, lambda _, dd: mjx.step(mm, dd), d)
            return d, (root_trace(d.qpos), d.qpos if record else None)

        _, (trace, qpos) = jax.lax.scan(control_step, data, jnp.arange(n_steps))
        trace = jnp.concatenate([root_trace(qpos0)[None], trace], 0)
        if record:
            return trace, jnp.concatenate([qpos0[None], qpos], 0)
        return trace

    return jax.vmap(one)(params)
