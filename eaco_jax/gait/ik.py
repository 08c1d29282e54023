"""Analytic leg inverse kinematics for a NAO-type leg (yaw, roll, pitch | pitch | pitch, roll).

The hip yaw, roll and pitch axes meet in one point, as do the ankle pitch and roll axes, so the
six joint angles follow in closed form from the ankle position relative to the hip (plus a foot
yaw), with the sole kept parallel to the torso. Conventions (NAO's, see ``robots/nao.xml``):
pitch axes +y (negative hip pitch = thigh forward, positive knee = bent), roll axes +x, yaw +z.
Everything is pure ``jax.numpy`` and works on any batch shape (vmap freely).
"""

from __future__ import annotations

import jax.numpy as jnp


def leg_ik(
    ankle: jnp.ndarray, yaw: jnp.ndarray, thigh: float, tibia: float
) -> jnp.ndarray:
    """Joint angles ``(..., 6)`` = (hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll).

    ``ankle`` ``(..., 3)`` is the ankle joint position relative to the hip joint point, in the
    torso frame (z down is negative); ``yaw`` is the foot yaw relative to the torso. Targets out
    of reach are clipped to a leg 0.1 % shorter than fully stretched.
    """
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    # ankle position in the frame rotated by the hip yaw
    x = c * ankle[..., 0] + s * ankle[..., 1]
    y = -s * ankle[..., 0] + c * ankle[..., 1]
    z = ankle[..., 2]
    roll = jnp.arctan2(y, -z)
    d = jnp.sqrt(y * y + z * z)  # leg length projected on the rolled sagittal plane
    length = jnp.sqrt(x * x + d * d)
    length = jnp.clip(length, abs(thigh - tibia) + 1e-4, (thigh + tibia) * 0.999)
    cos_knee = (thigh**2 + tibia**2 - length**2) / (2 * thigh * tibia)
    knee = jnp.pi - jnp.arccos(jnp.clip(cos_knee, -1.0, 1.0))
    cos_gamma = (thigh**2 + length**2 - tibia**2) / (2 * thigh * length)
    gamma = jnp.arccos(jnp.clip(cos_gamma, -1.0, 1.0))
    beta = jnp.arctan2(-x, d)
    hip_pitch = beta - gamma
    ankle_pitch = -(hip_pitch + knee)
    ankle_roll = -roll
    return jnp.stack([yaw * jnp.ones_like(x), roll, hip_pitch, knee, ankle_pitch, ankle_roll], -1)


def _rot(axis: str, angle: jnp.ndarray) -> jnp.ndarray:
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(angle), jnp.zeros_like(angle)
    if axis == "x":
        rows = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == "y":
        rows = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        rows = [[c, -s, z], [s, c, z], [z, z, o]]
    return jnp.stack([jnp.stack(r, -1) for r in rows], -2)


def leg_fk(q: jnp.ndarray, thigh: float, tibia: float) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Forward kinematics: ``(ankle position (..., 3), foot rotation (..., 3, 3))`` from ``q``.

    Same joint order as :func:`leg_ik`; used to test the IK by a round trip.
    """
    r_hip = _rot("z", q[..., 0]) @ _rot("x", q[..., 1]) @ _rot("y", q[..., 2])
    r_knee = r_hip @ _rot("y", q[..., 3])
    down = jnp.array([0.0, 0.0, -1.0])
    ankle = thigh * (r_hip @ down) + tibia * (r_knee @ down)
    foot = r_knee @ _rot("y", q[..., 4]) @ _rot("x", q[..., 5])
    return ankle, foot
