"""Leg inverse kinematics for any chain of hinge joints in an MJCF model (pure JAX).

A leg is the chain of hinge joints from the torso body down to a foot body or site. It is read
once from the ``mujoco.MjModel`` into a few arrays (:class:`LegChain`): per joint the fixed
transform from the previous joint's frame to this joint's anchor, and its axis; then the fixed
transform from the last joint to the foot point. The forward kinematics is MuJoCo's
(``mj_kinematics``: body offset, then a rotation about each joint axis through its anchor)
restricted to the chain: a handful of 3x3 products per joint instead of the whole model, and
its geometric Jacobian comes out of the same pass (``axis x (foot - anchor)``), with no
autodiff. Computing the chain alone, rather than MJX's full-model ``kinematics``, is what makes
a fixed-iteration solver cheap enough to run per control step for a whole colony; a test
checks it against MuJoCo's own kinematics.

:func:`solve` is damped least squares with the error-dependent damping of Levenberg-Marquardt
for IK (damping = squared task error + a small floor: Gauss-Newton near the target, gradient
steps far from it), a fixed number of iterations (``lax.fori_loop``, jittable, no
data-dependent control flow) and joint limits by projection after each step. The task is the
foot position, optionally with the foot orientation (e.g. the sole parallel to the ground
through the ankle joints). Chains of the same length stack into one :class:`LegChain` with a
leading axis, so legs, time steps and ants all vmap.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ProblemError


class LegChain(NamedTuple):
    """A leg's kinematic chain as arrays (a pytree; stack legs of equal length to vmap)."""

    offset_pos: jnp.ndarray  # (n, 3) previous joint frame -> joint anchor, in the previous frame
    offset_rot: jnp.ndarray  # (n, 3, 3) orientation of the joint frame in the previous frame
    axis: jnp.ndarray  # (n, 3) unit joint axis in the joint's frame
    end_pos: jnp.ndarray  # (3,) last joint frame -> foot point
    end_rot: jnp.ndarray  # (3, 3) orientation of the foot frame in the last joint frame
    lower: jnp.ndarray  # (n,) joint range
    upper: jnp.ndarray  # (n,)


def _quat_mat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def extract_chain(
    model, root_body: str, foot: str, point: np.ndarray | None = None
) -> tuple[LegChain, tuple[str, ...]]:
    """The chain of hinge joints from ``root_body`` to ``foot`` (a body or site name; for a body,
    ``point`` in its frame is the foot point, default its origin).

    Returns the chain (float32 arrays, torso frame = ``root_body``'s frame) and its joint names
    from the torso down. A foot that is not below the root body, a non-hinge joint on the way or
    a chain without joints is a :class:`ProblemError` naming the foot.
    """
    import mujoco

    obj = mujoco.mjtObj
    site = mujoco.mj_name2id(model, obj.mjOBJ_SITE, foot)
    if site >= 0:
        body = int(model.site_bodyid[site])
        end_p, end_r = model.site_pos[site].copy(), _quat_mat(model.site_quat[site])
    else:
        body = mujoco.mj_name2id(model, obj.mjOBJ_BODY, foot)
        if body < 0:
            raise ProblemError(f"leg foot {foot!r} is neither a body nor a site of the MJCF; "
                               "name a foot body or site of the model")
        end_p = np.zeros(3) if point is None else np.asarray(point, np.float64)
        end_r = np.eye(3)
    root = mujoco.mj_name2id(model, obj.mjOBJ_BODY, root_body)
    if root < 0:
        raise ProblemError(f"torso body {root_body!r} is not a body of the MJCF; name one")
    path = []
    b = body
    while b != root:
        if b == 0:
            raise ProblemError(f"leg foot {foot!r} is not below the torso body {root_body!r}; "
                               "name a foot inside the torso's subtree")
        path.append(b)
        b = int(model.body_parentid[b])
    path.reverse()
    hinge = mujoco.mjtJoint.mjJNT_HINGE
    cur_p, cur_r = np.zeros(3), np.eye(3)  # current frame in the previous joint's frame
    offs_p, offs_r, axes, lo, hi, names = [], [], [], [], [], []
    for b in path:
        cur_p = cur_p + cur_r @ model.body_pos[b]
        cur_r = cur_r @ _quat_mat(model.body_quat[b])
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            name = mujoco.mj_id2name(model, obj.mjOBJ_JOINT, j)
            if model.jnt_type[j] != hinge:
                raise ProblemError(f"leg to {foot!r}: joint {name!r} is not a hinge; only "
                                   "hinge joints can be solved, use a joint-space gait")
            anchor = model.jnt_pos[j]
            offs_p.append(cur_p + cur_r @ anchor)
            offs_r.append(cur_r)
            axes.append(model.jnt_axis[j] / np.linalg.norm(model.jnt_axis[j]))
            limited = bool(model.jnt_limited[j])
            lo.append(model.jnt_range[j, 0] if limited else -np.pi)
            hi.append(model.jnt_range[j, 1] if limited else np.pi)
            names.append(name)
            # after the rotation the frame sits at the anchor; the body origin is at -anchor
            cur_p, cur_r = -np.asarray(anchor, np.float64), np.eye(3)
    if not names:
        raise ProblemError(f"leg to {foot!r} has no joint between it and the torso; "
                           "name a foot below the leg's joints")
    end_p = cur_p + cur_r @ end_p
    end_r = cur_r @ end_r
    f = np.float32
    chain = LegChain(np.asarray(offs_p, f), np.asarray(offs_r, f), np.asarray(axes, f),
                     end_p.astype(f), end_r.astype(f), np.asarray(lo, f), np.asarray(hi, f))
    return chain, tuple(names)


def stack_chains(chains: list[LegChain]) -> LegChain:
    """Legs of equal joint count as one chain with a leading leg axis (vmap over it)."""
    sizes = {len(c.axis) for c in chains}
    if len(sizes) != 1:
        raise ProblemError(f"legs have different joint counts {sorted(sizes)}; legs solved "
                           "together need chains of equal length")
    return LegChain(*(np.stack(parts) for parts in zip(*chains, strict=True)))


def _axis_rot(axis: jnp.ndarray, angle: jnp.ndarray) -> jnp.ndarray:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues)."""
    x, y, z = axis[0], axis[1], axis[2]
    zero = jnp.zeros_like(x)
    k = jnp.stack([jnp.stack([zero, -z, y]), jnp.stack([z, zero, -x]),
                   jnp.stack([-y, x, zero])])
    return jnp.eye(3) + jnp.sin(angle) * k + (1.0 - jnp.cos(angle)) * (k @ k)


def fk_frames(chain: LegChain, q: jnp.ndarray):
    """Foot position ``(3,)``, foot rotation ``(3, 3)``, joint anchors ``(n, 3)`` and world
    axes ``(n, 3)``, all in the torso frame, for one leg at angles ``q`` ``(n,)``."""
    p, r = jnp.zeros(3, q.dtype), jnp.eye(3, dtype=q.dtype)
    anchors, axes = [], []
    for i in range(q.shape[0]):
        p = p + r @ chain.offset_pos[i]
        r = r @ chain.offset_rot[i]
        anchors.append(p)
        axes.append(r @ chain.axis[i])
        r = r @ _axis_rot(chain.axis[i], q[i])
    p = p + r @ chain.end_pos
    r = r @ chain.end_rot
    return p, r, jnp.stack(anchors), jnp.stack(axes)


def fk(chain: LegChain, q: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Foot ``(position (3,), rotation (3, 3))`` in the torso frame for one leg."""
    p, r, _, _ = fk_frames(chain, q)
    return p, r


def solve(
    chain: LegChain,
    target_pos: jnp.ndarray,
    q0: jnp.ndarray,
    target_rot: jnp.ndarray | None = None,
    iterations: int = 12,
    rot_scale: float = 0.1,
    damping: float = 1e-8,
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Joint angles ``(n,)`` within their ranges putting the foot at ``target_pos`` (torso
    frame), starting from ``q0``; also the remaining position error norm [m].

    With ``target_rot`` (3x3) the foot's orientation is matched too; its error (radians) is
    weighted by ``rot_scale`` metres so a milliradian counts like ``rot_scale`` millimetres.
    ``damping`` [m^2] is the floor of the Levenberg-Marquardt damping; ``iterations`` is fixed.
    """
    n = q0.shape[0]
    eye = jnp.eye(6 if target_rot is not None else 3, dtype=q0.dtype)

    def step(_, q):
        p, r, anchors, axes = fk_frames(chain, q)
        jp = jnp.cross(axes, p - anchors).T  # (3, n)
        err = target_pos - p
        jac = jp
        if target_rot is not None:
            # 0.5 sum_k r_k x rd_k = sin(angle) * axis of the rotation taking r to rd
            err_r = 0.5 * jnp.sum(jnp.cross(r.T, target_rot.T), axis=0)
            err = jnp.concatenate([err, rot_scale * err_r])
            jac = jnp.concatenate([jp, rot_scale * axes.T])
        lam = jnp.dot(err, err) + damping
        dq = jac.T @ jnp.linalg.solve(jac @ jac.T + lam * eye, err)
        return jnp.clip(q + dq, chain.lower, chain.upper)

    del n
    q = jax.lax.fori_loop(0, iterations, step, q0)
    p, _ = fk(chain, q)
    return q, jnp.linalg.norm(target_pos - p)
