"""A robot's legs for the generic-IK gait engines, read from its MJCF and standing pose.

Per leg: the kinematic chain from the torso to the foot (:mod:`eaco_jax.gait.ik_generic`), the
indices of its joints in the spec's actuator order, and, at the standing keyframe, the foot
point's position and orientation in the torso frame, the hip point (the chain's first joint
anchor), the side (+1 left, y > 0) and end (+1 front, x ahead of the feet's mean). Joints are
given roles by their axis at the standing pose (the first/last joint turning about the torso's
x or y axis is the hip/ankle roll/pitch), so the walk engine's joint-space compensations apply
to any humanoid leg with the usual yaw-roll-pitch | pitch | pitch-roll layout or a subset.

The feet are the spec's ``feet`` (body or site names) where it has them, else the bodies that
carry its ``foot_geoms``, in their first-appearance order (:func:`foot_names`).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ProblemError
from eaco_jax.gait.ik_generic import LegChain, extract_chain, fk_frames, stack_chains

ROLES: tuple[str, ...] = ("hip_roll", "hip_pitch", "ankle_pitch", "ankle_roll")


class LegSet(NamedTuple):
    """The legs of one robot (numpy constants; legs along the leading axis)."""

    feet: tuple[str, ...]
    joint_names: tuple[tuple[str, ...], ...]
    chain: LegChain  # stacked: every array has a leading leg axis
    joint_index: np.ndarray  # (L, n) positions of the chain joints in the spec's joint order
    stand_q: np.ndarray  # (L, n)
    stand_pos: np.ndarray  # (L, 3) foot point at the standing pose, torso frame
    stand_rot: np.ndarray  # (L, 3, 3)
    hip_pos: np.ndarray  # (L, 3) first joint anchor, torso frame
    side: np.ndarray  # (L,) +1 left, -1 right
    front: np.ndarray  # (L,) +1 front, -1 hind
    role_index: np.ndarray  # (L, len(ROLES)) chain joint of each role, -1 where none
    role_sign: np.ndarray  # (L, len(ROLES)) +1/-1: joint axis along +/- the torso axis
    stand_height: float  # mean vertical distance hip point -> foot point, standing


def foot_names(spec, model) -> tuple[tuple[str, np.ndarray | None], ...]:
    """The spec's feet as ``(body or site, point in a body's frame or None)``: its ``feet``
    field, else the bodies of its ``foot_geoms``, each with the point on the body's z axis at
    the height of its foot geoms' centroid (below the ankle for a sole, the sphere of a point
    foot), so a foot yaw about the vertical does not move the point."""
    feet = tuple(getattr(spec, "feet", ()) or ())
    if feet:
        return tuple((f, None) for f in feet)
    bodies: dict[str, list[np.ndarray]] = {}
    for g in spec.foot_geoms:
        geom = model.geom(g)
        bodies.setdefault(model.body(int(geom.bodyid[0])).name, []).append(geom.pos)
    return tuple((b, np.array([0.0, 0.0, float(np.mean(np.asarray(ps)[:, 2]))]))
                 for b, ps in bodies.items())


@functools.lru_cache(maxsize=16)
def leg_set(spec) -> LegSet:
    """The :class:`LegSet` of ``spec`` (cached per spec)."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(spec.xml_path)
    found = foot_names(spec, model)
    feet = tuple(f for f, _ in found)
    chains, names = [], []
    for foot, point in found:
        chain, joints = extract_chain(model, spec.torso_body, foot, point)
        missing = [j for j in joints if j not in spec.joint_names]
        if missing:
            raise ProblemError(f"leg to {foot!r}: joint {missing[0]!r} has no actuator in the "
                               "spec's joint_names; every leg joint needs one")
        chains.append(chain)
        names.append(joints)
    stacked = stack_chains(chains)
    index = np.array([[spec.joint_names.index(j) for j in js] for js in names])
    stand_q = np.asarray(spec.stand_ctrl, np.float32)[index]
    pos, rot, hip, roles, signs = [], [], [], [], []
    for chain, q in zip(chains, stand_q, strict=True):
        with jax.ensure_compile_time_eval():  # constants, also when first built in a trace
            p, r, anchors, axes = (np.asarray(a) for a in fk_frames(chain, jnp.asarray(q)))
        pos.append(p)
        rot.append(r)
        hip.append(anchors[0])
        idx, sgn = [], []
        for role in ROLES:
            k = 0 if role.endswith("roll") else 1
            hits = [i for i, a in enumerate(axes) if abs(a[k]) > 0.9]
            i = (hits[0] if role.startswith("hip") else hits[-1]) if hits else -1
            idx.append(i)
            sgn.append(float(np.sign(axes[i][k])) if i >= 0 else 0.0)
        roles.append(idx)
        signs.append(sgn)
    pos_a = np.asarray(pos, np.float32)
    hip_a = np.asarray(hip, np.float32)
    height = float(np.mean(hip_a[:, 2] - pos_a[:, 2]))
    if not height > 0.0:
        raise ProblemError(f"robot {spec.name}: the feet {list(feet)} are not below the hips "
                           "in the standing pose; fix stand_ctrl or the feet")
    return LegSet(
        feet=feet, joint_names=tuple(names), chain=stacked, joint_index=index,
        stand_q=stand_q, stand_pos=pos_a, stand_rot=np.asarray(rot, np.float32),
        hip_pos=hip_a, side=np.where(pos_a[:, 1] > 0.0, 1.0, -1.0).astype(np.float32),
        front=np.where(pos_a[:, 0] > pos_a[:, 0].mean(), 1.0, -1.0).astype(np.float32),
        role_index=np.asarray(roles), role_sign=np.asarray(signs, np.float32),
        stand_height=height)


@functools.lru_cache(maxsize=16)
def arm_swing(spec) -> tuple[tuple[int, float], ...]:
    """``(joint index, sign)`` of the spec's ``arm_swing_joints`` (left, right; empty without
    them): the sign makes a positive swing move a hanging arm backward, from the joint's axis
    (about the torso's y axis) in the standing pose."""
    import mujoco

    from eaco_jax.gait.robot import stand_qpos

    if not spec.arm_swing_joints:
        return ()
    model = mujoco.MjModel.from_xml_path(spec.xml_path)
    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(spec, model)
    mujoco.mj_kinematics(model, data)
    torso = np.asarray(data.xmat[model.body(spec.torso_body).id]).reshape(3, 3)
    out = []
    for name in spec.arm_swing_joints:
        axis = torso.T @ np.asarray(data.xaxis[model.joint(name).id])
        if abs(axis[1]) < 0.9:
            raise ProblemError(f"robot {spec.name}: arm_swing_joints {name!r} does not turn "
                               "about the torso's y axis (sideways) in the standing pose; name "
                               "the shoulder-pitch joints")
        out.append((spec.joint_names.index(name), float(np.sign(axis[1]))))
    return tuple(out)
