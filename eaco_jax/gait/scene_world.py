"""A scene's obstacles and ramps built into the robot's MuJoCo model (issue #32, walking).

:func:`scene_model` takes a :class:`~eaco_jax.problems.scenes.Scene` (pure data) and returns an
``MjModel``: the robot's MJCF (:func:`eaco_jax.gait.robot.model_xml`, flat floor) with every
obstacle and ramp added to the world body as a static geom.

* An **obstacle** (a prism: convex footprint, height) is a ``box`` where its footprint is a
  rectangle, else a convex ``mesh`` whose vertices are the footprint at the floor and at the
  prism's height. MuJoCo collides a mesh as its convex hull, which for a convex footprint is the
  prism itself, so both are exact.
* A **ramp** (a convex region of ground rising ``slope_deg`` towards ``uphill_deg``) is a convex
  mesh, a wedge: the footprint a little below the floor and the same footprint lifted onto the
  inclined plane that meets the floor along the ramp's lowest point. Its top is the inclined
  ground the planner prices; its raised sides are steps (up to the ramp's length along the
  uphill direction times the slope's tangent), which a walking robot meets only where a route
  enters or leaves a ramp other than across its low or high end.

Obstacles and ramps touch the robot's soles as the floor does (``contype`` / ``conaffinity`` of
the floor), so a foot that steps on them is stopped; the rest of the robot collides with
nothing, so a contact between the robot's body and an obstacle is found geometrically by
:func:`obstacle_distances` (``mj_geomDistance`` over every robot geom), not by the solver.
The geoms are named ``obstacle_<i>`` and ``ramp_<i>`` in the scene's order.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from eaco_jax.gait.robot import RobotSpec, model_xml

RAMP_BASE = 0.02
"""Depth [m] of a ramp wedge below the floor (so it has volume where it meets the floor)."""


def rectangle(poly: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, float] | None:
    """``(centre, half_sizes, yaw)`` of a counter-clockwise polygon that is a rectangle, else
    ``None`` (four corners, right angles within ``tol`` of the edge lengths)."""
    if len(poly) != 4:
        return None
    e = np.roll(poly, -1, axis=0) - poly
    lengths = np.linalg.norm(e, axis=1)
    scale = float(lengths.max())
    for k in range(4):
        if abs(float(e[k] @ e[(k + 1) % 4])) > tol * scale * scale:
            return None
    yaw = math.atan2(e[0, 1], e[0, 0])
    return poly.mean(axis=0), np.array([lengths[0] / 2, lengths[1] / 2]), yaw


def ramp_heights(poly: np.ndarray, slope_deg: float, uphill_deg: float) -> np.ndarray:
    """Height [m] of the ramp's surface above each point of ``poly`` (``(k, 2)``): zero at its
    lowest point, rising ``tan(slope)`` per metre towards ``uphill_deg`` (a negative slope
    rises the other way)."""
    u = np.array([math.cos(math.radians(uphill_deg)), math.sin(math.radians(uphill_deg))])
    along = np.asarray(poly) @ u
    if slope_deg < 0:
        along = -along
    return math.tan(math.radians(abs(slope_deg))) * (along - along.min())


def _yaw_quat(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


def scene_spec(scene: Any, spec: RobotSpec, accuracy: str = "fast",
               start_heading: float = 0.0) -> mujoco.MjSpec:
    """The robot's ``MjSpec`` with the scene's obstacles and ramps as static geoms and the
    robot standing at the scene's start facing ``start_heading`` [rad]."""
    ms = mujoco.MjSpec.from_string(model_xml(spec, 0.0, accuracy))
    floor = ms.geom("floor")
    world = ms.worldbody
    for i, ob in enumerate(scene.obstacles):
        poly = np.asarray(ob.polygon, np.float64)
        rect = rectangle(poly)
        common = dict(name=f"obstacle_{i}", contype=floor.contype, conaffinity=floor.conaffinity,
                      condim=3, friction=list(floor.friction), rgba=[0.55, 0.55, 0.6, 1.0])
        if rect is not None:
            centre, half, yaw = rect
            world.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX,
                           pos=[centre[0], centre[1], ob.height / 2],
                           size=[half[0], half[1], ob.height / 2], quat=_yaw_quat(yaw), **common)
        else:
            verts = np.concatenate([np.c_[poly, np.zeros(len(poly))],
                                    np.c_[poly, np.full(len(poly), ob.height)]])
            ms.add_mesh(name=f"obstacle_{i}_mesh", uservert=verts.reshape(-1).tolist())
            world.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"obstacle_{i}_mesh",
                           **common)
    for i, r in enumerate(scene.ramps):
        poly = np.asarray(r.polygon, np.float64)
        top = ramp_heights(poly, r.slope_deg, r.uphill_deg)
        verts = np.concatenate([np.c_[poly, np.full(len(poly), -RAMP_BASE)], np.c_[poly, top]])
        ms.add_mesh(name=f"ramp_{i}_mesh", uservert=verts.reshape(-1).tolist())
        world.add_geom(name=f"ramp_{i}", type=mujoco.mjtGeom.mjGEOM_MESH,
                       meshname=f"ramp_{i}_mesh", contype=floor.contype,
                       conaffinity=floor.conaffinity, condim=3, friction=list(floor.friction),
                       rgba=[0.8, 0.7, 0.5, 1.0])
    root = ms.body(spec.torso_body)
    root.pos = [scene.start[0], scene.start[1], spec.stand_root[2]]
    root.quat = _yaw_quat(start_heading)
    return ms


def scene_model(scene: Any, spec: RobotSpec, accuracy: str = "fast",
                start_heading: float = 0.0) -> mujoco.MjModel:
    """The compiled model of :func:`scene_spec` (robot at the start, obstacles, ramps)."""
    return scene_spec(scene, spec, accuracy, start_heading).compile()


def start_qpos(spec: RobotSpec, model: mujoco.MjModel, start: tuple[float, float],
               heading: float) -> np.ndarray:
    """Full ``qpos`` of the standing keyframe at ``start`` facing ``heading`` [rad]."""
    qpos = np.array(model.qpos0, np.float64)
    qpos[:7] = [start[0], start[1], spec.stand_root[2], *_yaw_quat(heading)]
    for name, value in zip(spec.joint_names, spec.stand_ctrl, strict=True):
        qpos[model.joint(name).qposadr[0]] = value
    return qpos


def geom_ids(model: mujoco.MjModel, prefix: str) -> list[int]:
    """Ids of the geoms named ``<prefix>_<i>``, in order."""
    out = []
    while True:
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{prefix}_{len(out)}")
        if gid < 0:
            return out
        out.append(gid)


def robot_geom_ids(model: mujoco.MjModel) -> list[int]:
    """Every geom of the robot (the geoms not on the world body)."""
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]


def obstacle_distances(model: mujoco.MjModel, data: mujoco.MjData, robot: list[int],
                       obstacles: list[int], near: np.ndarray, distmax: float) -> np.ndarray:
    """Least distance [m] between any robot geom and each obstacle geom flagged in ``near``
    (``distmax`` where farther or not flagged; negative: penetration), from the current
    ``data`` (after ``mj_forward`` / ``mj_step``)."""
    out = np.full(len(obstacles), distmax)
    for k, og in enumerate(obstacles):
        if not near[k]:
            continue
        best = distmax
        for rg in robot:
            d = mujoco.mj_geomDistance(model, data, rg, og, distmax, None)
            best = min(best, d)
        out[k] = best
    return out


__all__ = ["RAMP_BASE", "geom_ids", "obstacle_distances", "ramp_heights", "rectangle",
           "robot_geom_ids", "scene_model", "scene_spec", "start_qpos"]
