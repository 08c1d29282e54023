"""Closed-loop route walking batched over randomised worlds on MJX (issue #32, item 4).

The controller of :mod:`eaco_jax.gait.walk_route` (the same
:class:`~eaco_jax.gait.walk_route.Controller` settings, the same decisions) written as pure
JAX: one ``lax`` loop over control steps of
``vmap``-ed worlds, the decision gated to the control steps where a step cycle starts.

* **Per step cycle** (where the previous cycle's phase passed a whole cycle): the torso's heading
  averaged over the last cycle's control steps (circular mean), segment tracking
  (:func:`~eaco_jax.gait.walk_route.track`), the heading error to the target, the gait choice
  (:func:`~eaco_jax.gait.walk_route.choose`, turning on the spot included), the start-up rule
  (no switch during the walk engine's ramp) and the start of a new blend of parameters.
* **Per control step**: the blended parameters, the engine time that keeps the gait phase
  running on (``walk_route._phase_time``), the walk engine's targets, the world's latency and
  target noise, the push, ``substeps`` physics steps; then fall (torso height above the ground
  under it, ramps included, and tilt), goal and obstacle contact tests.

Worlds are :func:`~eaco_jax.gait.worlds.sample_worlds` on batch 0 of a stream of a run's seed,
drawn exactly as :func:`~eaco_jax.gait.walk_route.sample_walk_worlds` draws them for the same
count ``n``: the same friction (obstacles and ramps included), masses, motors, latency, initial
pose, push and target noise (``fold_in(noise_key, t)`` for control step ``t``). Threefry draws of
``n`` values are not prefixes of draws of more, so world ``i`` of ``n = 100`` is not world ``i``
of ``n = 20``: compare the backends on the same ``n``.

**Obstacle contact** is geometric, as on native MuJoCo (the robot's body geoms collide with
nothing in the physics; only its soles touch obstacles and ramps, as they touch the floor), but
analytic instead of ``mj_geomDistance``: the exact Euclidean distance between every robot geom
(19 spheres, 9 capsules and 3 boxes on the NAO) and every obstacle prism (convex footprint x
``[0, height]``) while they are apart, from the closest features (a point against the prism:
footprint distance and height distance combined; segment-segment distances between the capsule's
axis or the box's edges and the prism's edges; the box's corners against the prism and the
prism's corners against the box). Whether they overlap is exact too (clipping the capsule's
axis by the prism's planes; the separating-axis test for a box); an overlap's value is
negative but not MuJoCo's penetration depth. Distances are capped at ``distmax`` (1 m) as on
native.

The motor model is the native walker's ``motors`` setting
(:func:`~eaco_jax.gait.walk_route.motor_physics`): ``"servo"``, the scene model's actuators as
compiled (position servos with the MJCF's force clamp, targets held); ``"spec"``, the robot
spec's motor model as the gait rollouts apply it: the limits in the physics through
:mod:`eaco_jax.gait.rollout_mjx`'s direct-torque path
(:func:`~eaco_jax.gait.quality.motor_torque` each physics step) and the targets interpolated
toward the next control step's (:func:`~eaco_jax.gait.motors.physics_targets`; the next
step's target is the blend where it stands, which a new cycle's decision does not change).
``limits=True`` alone applies the limits with held targets.
``impl="warp"`` runs MuJoCo Warp (CUDA) with contact buffers sized for the NAO's soles on the
floor plus :data:`SCENE_CONTACTS_PER_SOLE` obstacle or ramp contacts per sole.
Only every ``record_every``-th control step's ``(x, y, yaw, mode)`` is kept.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait import scene_world as sw
from eaco_jax.gait import walk_route as wr
from eaco_jax.gait.mjx_import import quiet_mjx
from eaco_jax.gait.robot import RobotSpec
from eaco_jax.gait.rollout_mjx import (
    IMPLS,
    _torque_fields,
    _warp_model,
    _warp_overflow,
    _world_model,
    contact_capacity,
    warp_pairs,
)
from eaco_jax.gait.rollout_native import native_model, to_torque_actuators
from eaco_jax.gait.walk_engine import LOWER, PARAM_NAMES, RAMP_TIME, joint_targets
from eaco_jax.gait.worlds import (
    VARIED_FIELDS,
    RobustConfig,
    Worlds,
    actuated_dofs,
    couple_controls,
    friction_geom_ids,
    initial_qpos,
    model_fields,
)

mjx = quiet_mjx()

TURN = PARAM_NAMES.index("turn_rate")
PERIOD = PARAM_NAMES.index("period")
STEP = PARAM_NAMES.index("step_length")
SCENE_CONTACTS_PER_SOLE = 2
"""Obstacle or ramp contacts a sole sphere may have at once besides the floor (MuJoCo Warp's
buffers; an overflow is reported on stderr)."""
PHASE_TOL = 1e-6
"""A step cycle ends where the phase is within this of the next whole cycle (float32)."""


# --------------------------------------------------------------------------- geometry
def _seg_seg(p1, q1, p2, q2):
    """Distance between segments ``p1q1`` and ``p2q2`` (broadcast over leading axes)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = jnp.sum(d1 * d1, -1)
    e = jnp.sum(d2 * d2, -1)
    f = jnp.sum(d2 * r, -1)
    c = jnp.sum(d1 * r, -1)
    b = jnp.sum(d1 * d2, -1)
    eps = 1e-12
    denom = a * e - b * b
    s = jnp.where(denom > eps, jnp.clip((b * f - c * e) / jnp.maximum(denom, eps), 0.0, 1.0), 0.0)
    t = (b * s + f) / jnp.maximum(e, eps)
    s = jnp.where(t < 0, jnp.clip(-c / jnp.maximum(a, eps), 0.0, 1.0), s)
    s = jnp.where(t > 1, jnp.clip((b - c) / jnp.maximum(a, eps), 0.0, 1.0), s)
    t = jnp.clip(t, 0.0, 1.0)
    s = jnp.where(a > eps, s, 0.0)
    t = jnp.where(e > eps, t, 0.0)
    diff = (p1 + d1 * s[..., None]) - (p2 + d2 * t[..., None])
    return jnp.sqrt(jnp.sum(diff * diff, -1) + 1e-20)


@dataclasses.dataclass(frozen=True)
class _Prisms:
    """Obstacle prisms, footprints padded to ``V`` vertices by repeating the last one."""

    poly: np.ndarray  # (O, V, 2) counter-clockwise
    height: np.ndarray  # (O,)
    valid: np.ndarray  # (O, V) edge i (vertex i -> i + 1) has length

    @staticmethod
    def of(obstacles) -> _Prisms:
        polys = [np.asarray(o.polygon, np.float64) for o in obstacles]
        v = max((len(p) for p in polys), default=3)
        poly = np.zeros((len(polys), v, 2))
        for i, p in enumerate(polys):
            poly[i, : len(p)] = p
            poly[i, len(p):] = p[-1]
        edge = np.roll(poly, -1, axis=1) - poly
        valid = np.linalg.norm(edge, axis=-1) > 1e-9
        return _Prisms(poly.astype(np.float32),
                       np.array([o.height for o in obstacles], np.float32), valid)

    def edges3(self) -> tuple[np.ndarray, np.ndarray]:
        """Every prism's edges ``(O, 3V, 3)`` start and end points: bottom, top, vertical."""
        p = self.poly
        q = np.roll(p, -1, axis=1)
        z0 = np.zeros(p.shape[:2] + (1,), np.float32)
        zh = np.broadcast_to(self.height[:, None, None], z0.shape)
        bottom = (np.concatenate([p, z0], -1), np.concatenate([q, z0], -1))
        top = (np.concatenate([p, zh], -1), np.concatenate([q, zh], -1))
        vert = (np.concatenate([p, z0], -1), np.concatenate([p, zh], -1))
        a = np.concatenate([bottom[0], top[0], vert[0]], 1)
        b = np.concatenate([bottom[1], top[1], vert[1]], 1)
        return a.astype(np.float32), b.astype(np.float32)

    def corners(self) -> np.ndarray:
        """``(O, 2V, 3)`` corners of every prism."""
        p = self.poly
        z0 = np.zeros(p.shape[:2] + (1,), np.float32)
        zh = np.broadcast_to(self.height[:, None, None], z0.shape)
        return np.concatenate([np.concatenate([p, z0], -1), np.concatenate([p, zh], -1)], 1)


def _prism_point(x, poly, height, valid):
    """Signed distance from points ``x`` ``(..., 3)`` to one prism (negative inside)."""
    a = jnp.asarray(poly)
    b = jnp.roll(a, -1, axis=0)
    d = b - a  # (V, 2)
    w = x[..., None, :2] - a  # (..., V, 2)
    dd = jnp.maximum(jnp.sum(d * d, -1), 1e-12)
    t = jnp.clip(jnp.sum(w * d, -1) / dd, 0.0, 1.0)
    seg = jnp.sqrt(jnp.sum((w - t[..., None] * d) ** 2, -1) + 1e-20)
    cross = d[:, 0] * w[..., 1] - d[:, 1] * w[..., 0]  # >= 0 inside (ccw)
    inside = jnp.all(jnp.where(valid, cross >= 0, True), -1)
    line = jnp.where(valid, cross / jnp.sqrt(dd), jnp.inf)  # depth inside each edge
    dxy = jnp.where(inside, 0.0, jnp.min(seg, -1))
    z = x[..., 2]
    dz = jnp.maximum(jnp.maximum(-z, z - height), 0.0)
    depth = jnp.minimum(jnp.min(line, -1), jnp.minimum(z, height - z))
    out = jnp.sqrt(dxy * dxy + dz * dz + 1e-20)
    return jnp.where(inside & (dz <= 0), -depth, out)


def _prism_planes(poly, height, valid):
    """Outward unit normals ``(V + 2, 3)`` and offsets of a prism's faces (invalid: zero)."""
    a = jnp.asarray(poly)
    d = jnp.roll(a, -1, axis=0) - a
    n = jnp.stack([d[:, 1], -d[:, 0]], -1) / jnp.maximum(jnp.linalg.norm(d, axis=-1), 1e-12)[
        :, None]
    n = jnp.where(jnp.asarray(valid)[:, None], n, 0.0)
    n3 = jnp.concatenate([n, jnp.zeros((n.shape[0], 1))], -1)
    off = jnp.sum(n * a, -1)
    normals = jnp.concatenate([n3, jnp.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])], 0)
    offsets = jnp.concatenate([off, jnp.stack([jnp.asarray(height), jnp.zeros(())])])
    return normals, offsets


def _segment_hits(p, q, normals, offsets):
    """Whether segments ``p -> q`` ``(..., 3)`` meet the convex solid ``n . x <= off``."""
    d = q - p
    num = offsets - jnp.sum(p[..., None, :] * normals, -1)  # (..., F)
    den = jnp.sum(d[..., None, :] * normals, -1)
    zero = jnp.abs(den) < 1e-12
    t = num / jnp.where(zero, 1.0, den)
    enter = jnp.max(jnp.where(~zero & (den < 0), t, 0.0), -1)
    leave = jnp.min(jnp.where(~zero & (den > 0), t, 1.0), -1)
    outside_parallel = jnp.any(zero & (num < 0), -1)
    return (enter <= leave) & ~outside_parallel


def _box_point(x, centre, rot, half):
    """Distance from points ``x`` ``(..., 3)`` to a box (0 inside)."""
    local = jnp.einsum("...i,ij->...j", x - centre, rot)
    excess = jnp.maximum(jnp.abs(local) - half, 0.0)
    return jnp.sqrt(jnp.sum(excess * excess, -1) + 1e-20)


_BOX_SIGNS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], np.float32)
_BOX_EDGES = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                       if np.sum(_BOX_SIGNS[a] != _BOX_SIGNS[b]) == 1])  # (12, 2)


@dataclasses.dataclass(frozen=True)
class _RobotGeoms:
    spheres: np.ndarray  # geom ids
    sphere_r: np.ndarray
    capsules: np.ndarray
    capsule_r: np.ndarray
    capsule_half: np.ndarray
    boxes: np.ndarray
    box_half: np.ndarray  # (nb, 3)

    @staticmethod
    def of(model: mujoco.MjModel) -> _RobotGeoms:
        ids = np.asarray(sw.robot_geom_ids(model))
        gtype = model.geom_type[ids]
        known = (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE,
                 mujoco.mjtGeom.mjGEOM_BOX)
        if not np.all(np.isin(gtype, [int(k) for k in known])):
            bad = sorted({int(t) for t in gtype} - {int(k) for k in known})
            raise ProblemError(f"obstacle contact on MJX handles sphere, capsule and box robot "
                               f"geoms; this robot has geom types {bad}: walk it on native")
        s = ids[gtype == mujoco.mjtGeom.mjGEOM_SPHERE]
        c = ids[gtype == mujoco.mjtGeom.mjGEOM_CAPSULE]
        b = ids[gtype == mujoco.mjtGeom.mjGEOM_BOX]
        size = model.geom_size.astype(np.float32)
        return _RobotGeoms(s, size[s, 0], c, size[c, 0], size[c, 1], b, size[b])


def obstacle_distances(geom_xpos, geom_xmat, geoms: _RobotGeoms, prisms: _Prisms,
                       distmax: float) -> jax.Array:
    """Least distance ``(O,)`` between any robot geom and each obstacle prism of one world
    (``distmax`` where farther; negative: overlapping), from the geoms' world poses
    ``geom_xpos`` ``(ngeom, 3)`` and ``geom_xmat`` ``(ngeom, 9)`` or ``(ngeom, 3, 3)``."""
    o = len(prisms.height)
    if o == 0:
        return jnp.zeros((0,), jnp.float32)
    xmat = jnp.reshape(geom_xmat, (geom_xmat.shape[0], 3, 3))
    ea, eb = (jnp.asarray(e) for e in prisms.edges3())  # (O, E, 3)
    corners = jnp.asarray(prisms.corners())  # (O, C, 3)

    def one(poly, height, valid, ea_, eb_, corners_):
        out = jnp.asarray(distmax, jnp.float32)
        normals, offsets = _prism_planes(poly, height, valid)
        if len(geoms.spheres):
            d = _prism_point(geom_xpos[geoms.spheres], poly, height, valid) - geoms.sphere_r
            out = jnp.minimum(out, jnp.min(d))
        if len(geoms.capsules):
            centre = geom_xpos[geoms.capsules]
            axis = xmat[geoms.capsules][:, :, 2] * jnp.asarray(geoms.capsule_half)[:, None]
            p, q = centre - axis, centre + axis
            ends = jnp.minimum(_prism_point(p, poly, height, valid),
                               _prism_point(q, poly, height, valid))
            edges = jnp.min(_seg_seg(p[:, None], q[:, None], ea_[None], eb_[None]), -1)
            hit = _segment_hits(p, q, normals, offsets)
            d = jnp.where(hit, jnp.minimum(ends, 0.0), jnp.minimum(ends, edges))
            out = jnp.minimum(out, jnp.min(d - geoms.capsule_r))
        if len(geoms.boxes):
            out = jnp.minimum(out, jnp.min(jax.vmap(
                lambda c, r, h: _box_prism(c, r, h, poly, height, valid, normals, ea_, eb_,
                                           corners_))(
                geom_xpos[geoms.boxes], xmat[geoms.boxes], jnp.asarray(geoms.box_half))))
        return out

    return jax.vmap(one)(jnp.asarray(prisms.poly), jnp.asarray(prisms.height),
                         jnp.asarray(prisms.valid), ea, eb, corners)


def _box_prism(centre, rot, half, poly, height, valid, normals, ea, eb, corners):
    """Distance between a box and a prism: exact while apart (closest features), the
    separating-axis overlap (negative) when they meet."""
    verts = centre + (jnp.asarray(_BOX_SIGNS) * half) @ rot.T  # (8, 3)
    e = jnp.asarray(_BOX_EDGES)
    ba, bb = verts[e[:, 0]], verts[e[:, 1]]
    # separating axes: prism faces, box faces, box edge x prism edge directions
    pdirs = jnp.concatenate([eb - ea], 0)
    cross = jnp.cross(rot.T[:, None, :], pdirs[None, :, :]).reshape(-1, 3)
    axes = jnp.concatenate([normals, rot.T, cross], 0)
    norm = jnp.linalg.norm(axes, axis=-1)
    ok = norm > 1e-6
    axes = axes / jnp.where(ok, norm, 1.0)[:, None]
    pb = verts @ axes.T  # (8, A)
    pp = corners @ axes.T  # (C, A)
    sep = jnp.maximum(jnp.min(pp, 0) - jnp.max(pb, 0), jnp.min(pb, 0) - jnp.max(pp, 0))
    sep = jnp.max(jnp.where(ok, sep, -jnp.inf))
    apart = jnp.minimum(
        jnp.minimum(jnp.min(_prism_point(verts, poly, height, valid)),
                    jnp.min(_box_point(corners, centre, rot, half))),
        jnp.min(_seg_seg(ba[:, None], bb[:, None], ea[None], eb[None])))
    return jnp.where(sep > 0, apart, sep)


# --------------------------------------------------------------------------- ground
def _ramp_arrays(scene: Any):
    planes = wr._ramp_planes(scene)
    if not planes:
        return None
    v = max(len(p[0]) for p in planes)
    poly = np.zeros((len(planes), v, 2), np.float32)
    for i, (p, _, _, _) in enumerate(planes):
        poly[i, : len(p)] = p
        poly[i, len(p):] = p[-1]
    u = np.array([p[1] for p in planes], np.float32)
    tan = np.array([p[2] for p in planes], np.float32)
    low = np.array([p[3] for p in planes], np.float32)
    return poly, u, tan, low


def _ground(ramps, xy):
    """Ground height under ``xy`` (the first ramp containing it, else the floor)."""
    if ramps is None:
        return jnp.zeros(())
    poly, u, tan, low = (jnp.asarray(a) for a in ramps)
    e = jnp.roll(poly, -1, axis=1) - poly
    w = xy - poly
    inside = jnp.all(e[..., 0] * w[..., 1] - e[..., 1] * w[..., 0] >= 0, -1)  # (R,)
    h = tan * (u @ xy - low)
    first = jnp.argmax(inside)
    return jnp.where(jnp.any(inside), h[first], 0.0)


# --------------------------------------------------------------------------- controller
def _choose(error, mode, c: wr.Controller):
    """:func:`~eaco_jax.gait.walk_route.choose` in JAX: ``(mode, steer, step)``."""
    big, small = math.radians(c.turn_deg), math.radians(c.resume_deg)
    turning = mode != 0
    overshot = ((mode == 1) & (error < 0)) | ((mode == 2) & (error > 0))
    keep = turning & ~overshot & (jnp.abs(error) > small)
    spot = ~keep & (jnp.abs(error) > big) & ~overshot
    steer = jnp.clip(c.steer_gain * error, -c.max_steer, c.max_steer)
    step = _step_fraction(jnp.abs(error), c)
    new = jnp.where(keep, mode, jnp.where(spot, jnp.where(error > 0, 1, 2), 0))
    fwd = new == 0
    return new, jnp.where(fwd, steer, 0.0), jnp.where(fwd, step, 1.0)


def _start_cap(t, c: wr.Controller):
    """:func:`~eaco_jax.gait.walk_route.start_cap` in JAX (``start_ramp_s`` > 0)."""
    return jnp.clip(t / c.start_ramp_s, c.min_step, 1.0)


def _pick_cell(speed, stp):
    """:func:`~eaco_jax.gait.walk_route.pick_cell` in JAX (``speed``: the cells' speeds,
    slowest first)."""
    return jnp.maximum(jnp.sum(speed <= stp * speed[-1] + 1e-6) - 1, 0).astype(jnp.int32)


def _step_fraction(error, c: wr.Controller):
    """:func:`~eaco_jax.gait.walk_route.step_fraction` in JAX (``error`` >= 0, rad)."""
    u = (jnp.degrees(error) - c.slow_deg) / (c.stop_deg - c.slow_deg)
    return 1.0 - (1.0 - c.min_step) * jnp.clip(u, 0.0, 1.0)


def _bend_cap(route, seg, pos, c: wr.Controller):
    """:func:`~eaco_jax.gait.walk_route.bend_cap` in JAX."""
    if c.bend_distance <= 0:
        return jnp.float32(1.0)
    last = route.shape[0] - 2  # seg <= last, so seg + 1 is a waypoint; seg + 2 may not be
    a, b, n = route[seg], route[seg + 1], route[jnp.minimum(seg + 2, last + 1)]
    turn = jnp.abs(_wrap(jnp.arctan2(n[1] - b[1], n[0] - b[0])
                         - jnp.arctan2(b[1] - a[1], b[0] - a[0])))
    near = jnp.clip(1.0 - jnp.linalg.norm(b - pos) / c.bend_distance, 0.0, 1.0)
    return jnp.where(seg < last, _step_fraction(turn * near, c), 1.0)


def _choose_near(error, mode, near, c: wr.Controller):
    """:func:`_choose` with :func:`~eaco_jax.gait.walk_route.near_goal`'s controller where
    ``near`` (within ``lookahead`` of the goal on the last segment)."""
    out = _choose(error, mode, c)
    if c.goal_turn_deg >= 180:
        return out
    alt = _choose(error, mode, wr.near_goal(c))
    return tuple(jnp.where(near, a, b) for a, b in zip(alt, out, strict=True))


def _track(route, seg, pos, c: wr.Controller):
    """:func:`~eaco_jax.gait.walk_route.track` in JAX."""
    last = route.shape[0] - 2

    def geometry(s):
        a, b = route[s], route[s + 1]
        d = b - a
        length = jnp.linalg.norm(d)
        unit = d / jnp.maximum(length, 1e-12)
        return a, b, length, unit, jnp.dot(pos - a, unit)

    def advance(_, s):
        _, b, length, _, along = geometry(s)
        go = (s < last) & ((along >= length - c.capture) | (jnp.linalg.norm(pos - b)
                                                           <= c.capture))
        return jnp.where(go, s + 1, s)

    seg = jax.lax.fori_loop(0, last + 1, advance, seg)
    a, _, length, unit, along = geometry(seg)
    return seg, a + unit * jnp.minimum(length, jnp.maximum(along, 0.0) + c.lookahead)


def _wrap(a):
    return jnp.mod(a + jnp.pi, 2 * jnp.pi) - jnp.pi


def _yaw(q):
    w, x, y, z = q[..., 3], q[..., 4], q[..., 5], q[..., 6]
    return jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


# --------------------------------------------------------------------------- inputs
@dataclasses.dataclass
class WalkBatch:
    """What the batched walk needs of its worlds (leading axis B on every array)."""

    fields: dict  # varied model fields (B, ...)
    qpos: np.ndarray  # (B, nq) initial configuration
    latency: np.ndarray  # (B,) int
    noise_key: Any  # key of the target noise (None: no noise)
    noise_std: np.ndarray  # (B,) rad (0: none)
    noise_rows: np.ndarray  # (B,) row of each world in the draw of n_draw worlds
    n_draw: int
    push_start: np.ndarray  # (B,)
    push_stop: np.ndarray
    push_force: np.ndarray  # (B, 3)
    stall_scale: np.ndarray  # (B, nu)
    speed_scale: np.ndarray
    index: list[int]  # world index of each row (-1: nominal)


def _base_fields(model) -> dict:
    return {f: np.asarray(getattr(model, f), np.float32) for f in VARIED_FIELDS}


def nominal_batch(model: mujoco.MjModel, spec: RobotSpec, start, heading: float) -> WalkBatch:
    """The nominal world as a batch of one (no noise, latency or push)."""
    q = sw.start_qpos(spec, model, tuple(start), heading)
    fields = {k: v[None] for k, v in _base_fields(model).items()}
    nu = spec.nu
    return WalkBatch(fields, q[None].astype(np.float32), np.zeros(1, np.int32), None,
                     np.zeros(1, np.float32), np.zeros(1, np.int32), 1,
                     np.full(1, -1, np.int32), np.full(1, -1, np.int32),
                     np.zeros((1, 3), np.float32), np.ones((1, nu), np.float32),
                     np.ones((1, nu), np.float32), [-1])


def with_nominal(batch: WalkBatch, model: mujoco.MjModel, spec: RobotSpec, start,
                 heading: float) -> WalkBatch:
    """``batch`` with the nominal world prepended as row 0 (index -1), so that one compiled
    call walks both."""
    nom = nominal_batch(model, spec, start, heading)
    cat = lambda a, b: np.concatenate([np.asarray(a), np.asarray(b)], 0)  # noqa: E731
    return WalkBatch({k: cat(nom.fields[k], v) for k, v in batch.fields.items()},
                     cat(nom.qpos, batch.qpos), cat(nom.latency, batch.latency),
                     batch.noise_key, cat(nom.noise_std, batch.noise_std),
                     cat(nom.noise_rows, batch.noise_rows), batch.n_draw,
                     cat(nom.push_start, batch.push_start), cat(nom.push_stop, batch.push_stop),
                     cat(nom.push_force, batch.push_force),
                     cat(nom.stall_scale, batch.stall_scale),
                     cat(nom.speed_scale, batch.speed_scale), [-1] + list(batch.index))


def world_batch(model: mujoco.MjModel, spec: RobotSpec, n: int, push_steps: int, start,
                heading: float, seed: int = 0, stream: str = "test",
                cfg: RobustConfig | None = None, index=None) -> tuple[WalkBatch, Worlds]:
    """Worlds ``index`` (default all) of the ``n`` that
    :func:`~eaco_jax.gait.walk_route.sample_walk_worlds` draws for ``seed`` / ``stream``."""
    worlds = wr.walk_worlds(model, spec, n, push_steps, seed, stream, cfg)
    wn = jax.tree.map(np.asarray, worlds)
    idx = np.arange(n) if index is None else np.asarray(index, np.int64)
    if idx.size == 0 or idx.min() < 0 or idx.max() >= n:
        raise ConfigError(f"world indices must be in [0, {n}), got {idx.tolist()}")
    fields = model_fields(_base_fields(model), wn, friction_geom_ids(model, spec),
                          actuated_dofs(model, spec), xp=np)
    extra = sw.geom_ids(model, "ramp") + sw.geom_ids(model, "obstacle")
    fr = np.array(fields["geom_friction"], copy=True)
    if extra:
        fr[:, extra, 0] = wn.friction[:, None]
    fields["geom_friction"] = fr
    fields = {k: np.asarray(v, np.float32)[idx] for k, v in fields.items()}
    qadr = np.array([model.joint(j).qposadr[0] for j in spec.joint_names])
    stand = sw.start_qpos(spec, model, (0.0, 0.0), 0.0)
    qinit = initial_qpos(stand, wn, qadr, np.asarray(spec.joint_lower),
                         np.asarray(spec.joint_upper), xp=np)[idx]
    qinit[:, :2] = start
    qinit[:, 3:7] = [math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2)]
    batch = WalkBatch(fields, qinit.astype(np.float32), wn.latency[idx].astype(np.int32),
                      worlds.noise_key, np.full(len(idx), float(wn.noise_std), np.float32),
                      idx.astype(np.int32), n,
                      wn.push_start[idx], wn.push_stop[idx], wn.push_force[idx],
                      wn.stall_scale[idx], wn.speed_scale[idx], idx.tolist())
    return batch, worlds


# --------------------------------------------------------------------------- the walk
def _ramp_steps(dt: float) -> int:
    """Control steps ``k`` with ``k dt < RAMP_TIME`` (the native walker's test, float64)."""
    k = 0
    while k * dt < RAMP_TIME:
        k += 1
    return k


def check_impl(impl: str) -> None:
    """One line for an MJX implementation that cannot run here."""
    from eaco_jax.gait.mjx_import import warp_usable

    if impl not in IMPLS:
        raise ConfigError(f"impl must be one of {', '.join(IMPLS)}, got {impl!r}")
    if impl == "warp" and not warp_usable():
        raise ConfigError("impl 'warp' needs a CUDA GPU and warp-lang (pip install "
                          "'eaco-jax[gpu]'); use --impl jax")


def walk_batch(scene: Any, route: np.ndarray, spec: RobotSpec, gaits: wr.WalkGaits,
               ctrl: wr.Controller, batch: WalkBatch, *, max_time: float,
               model: mujoco.MjModel | None = None, impl: str = "jax",
               limits: bool = False, record_every: int = 5,
               distmax: float = 1.0, motors: str = "servo") -> dict[str, np.ndarray]:
    """Walk ``route`` in every world of ``batch`` at once (one jitted call); per-world arrays
    (see :func:`records` for the native walker's record of each). ``motors``: ``"servo"`` or
    ``"spec"`` (:func:`~eaco_jax.gait.walk_route.motor_physics`); ``limits`` also applies the
    motor limits under ``"servo"``."""
    check_impl(impl)
    spec_limits, interpolate = wr.motor_physics(spec, motors)
    route = np.asarray(route, np.float64)
    if route.ndim != 2 or route.shape[1] != 2 or len(route) < 2:
        raise ProblemError(f"route must be (k >= 2, 2) waypoints, got shape {route.shape}")
    if not (math.isfinite(max_time) and max_time > 0):
        raise ConfigError(f"max_time must be a finite number > 0, got {max_time!r}")
    dt = spec.control_dt
    if not (isinstance(record_every, int) and record_every >= 1
            and record_every * dt <= float(LOWER[PERIOD]) / 2):
        raise ConfigError(f"record_every must be an integer in [1, "
                          f"{int(float(LOWER[PERIOD]) / 2 / dt)}] (at most one step cycle "
                          f"starts between samples), got {record_every!r}")
    heading0 = wr.start_heading(scene, route)
    if model is None:
        model = sw.scene_model(scene, spec, start_heading=heading0)
    n_steps = int(math.ceil(max_time / dt))
    fn = _compiled(_Static.of(scene, route, spec, gaits, ctrl, model, impl,
                              bool(limits) or spec_limits, record_every, distmax, n_steps,
                              len(batch.index), int(np.max(batch.latency)) + 1, interpolate))
    key = batch.noise_key if batch.noise_key is not None else jax.random.PRNGKey(0)
    inputs = (jnp.asarray(route, jnp.float32), jnp.float32(heading0), jnp.asarray(batch.qpos),
              {k: jnp.asarray(v) for k, v in batch.fields.items()},
              jnp.asarray(batch.latency), key, jnp.asarray(batch.noise_std, jnp.float32),
              jnp.asarray(batch.noise_rows), jnp.asarray(batch.push_start),
              jnp.asarray(batch.push_stop), jnp.asarray(batch.push_force, jnp.float32),
              jnp.asarray(batch.stall_scale, jnp.float32),
              jnp.asarray(batch.speed_scale, jnp.float32))
    out = jax.tree.map(np.asarray, fn(*inputs, n_draw=batch.n_draw))
    out["index"] = np.asarray(batch.index)
    out["dt"] = dt
    out["record_every"] = record_every
    out["n_steps"] = n_steps
    out["distmax"] = distmax
    out["motors"] = motors
    out["has_currents"] = mo.motor_model(spec) is not None
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class _Static:
    """Everything the compiled walk closes over (hashed by its key: the route's waypoints are
    an argument, only their number is compiled in)."""

    key: tuple
    scene: Any
    route: np.ndarray
    spec: RobotSpec
    lib: np.ndarray
    ctrl: wr.Controller
    model: mujoco.MjModel
    impl: str
    limits: bool
    record_every: int
    distmax: float
    n_steps: int
    batch: int
    lat_max: int
    interpolate: bool = False
    cells: tuple | None = None  # (cells (K, P), speed (K,)) float32, or None

    @staticmethod
    def of(scene, route, spec, gaits, ctrl, model, impl, limits, record_every, distmax,
           n_steps, batch, lat_max, interpolate=False) -> _Static:
        lib = np.stack([gaits.of(m) for m in wr.MODES]).astype(np.float32)
        cells = None if gaits.cells is None else tuple(
            np.asarray(a, np.float32) for a in (gaits.cells, gaits.cell_speed))
        key = (id(model), id(scene), len(route), spec.name, lib.tobytes(), ctrl, impl,
               bool(limits), record_every, distmax, n_steps, batch, lat_max,
               bool(interpolate), None if cells is None else b"".join(a.tobytes() for a in cells))
        return _Static(key, scene, route, spec, lib, ctrl, model, impl, bool(limits),
                       record_every, float(distmax), n_steps, batch, lat_max,
                       bool(interpolate), cells)

    def __hash__(self) -> int:
        return hash(self.key)

    def __eq__(self, other) -> bool:
        return isinstance(other, _Static) and self.key == other.key


@functools.lru_cache(maxsize=4)
def _compiled(st: _Static):
    """The jitted batched walk for one scene model, route length, controller and batch
    size."""
    spec, c, model = st.spec, st.ctrl, st.model
    dt = spec.control_dt
    sub = int(round(dt / model.opt.timestep))
    nb, nu = st.batch, spec.nu
    last_seg = len(st.route) - 2
    lib = jnp.asarray(st.lib)
    n_cells = 0 if st.cells is None else len(st.cells[0])
    if n_cells:
        cells, cell_speed = (jnp.asarray(a) for a in st.cells)

        def pick(stp):
            return _pick_cell(cell_speed, stp)
    ramp_steps = _ramp_steps(dt)
    geoms = _RobotGeoms.of(model)
    prisms = _Prisms.of(st.scene.obstacles)
    ramps = _ramp_arrays(st.scene)
    cos_tilt = math.cos(math.radians(spec.fall_tilt_deg))
    dofs = np.asarray(actuated_dofs(model, spec))
    qadr = np.array([model.joint(n).qposadr[0] for n in spec.joint_names])
    lat_max = st.lat_max
    warp = st.impl == "warp"
    phys_model = model
    if st.limits:
        if mo.motor_model(spec) is None:
            raise ConfigError(f"robot {spec.name}: no electrical motor data, no limits to apply")
        phys_model = to_torque_actuators(copy.copy(model), dofs, mo.friction_share(spec))
    mm = _warp_model(phys_model) if warp else mjx.put_model(phys_model)
    if warp:
        floor, rows = contact_capacity(native_model(spec, 0.0, "fast"))  # robot + floor
        soles = int(np.sum(model.geom_contype[sw.robot_geom_ids(model)] > 0))
        scene_geoms = len(sw.geom_ids(model, "obstacle")) + len(sw.geom_ids(model, "ramp"))
        extra = soles * min(scene_geoms, SCENE_CONTACTS_PER_SOLE)
        per_world = floor + extra
        condim = int(np.max(model.geom_condim))
        njmax = rows + extra * max(1, 2 * (condim - 1))
        naconmax = per_world * nb
        dw = mjx.make_data(model, impl="warp", naconmax=naconmax, njmax=njmax)
    mlim = mo.motor_model(spec)  # None: no electrical data (no limits, no currents)
    n_samples = -(-st.n_steps // st.record_every)

    def run(route, heading0, qpos0, fields, latency, noise_key, noise_std, noise_rows,
            push_start, push_stop, push_force, stall_scale, speed_scale, *, n_draw):
        goal = route[-1]
        servo_fields = fields
        if st.limits:
            fields = _torque_fields(fields, dofs, mo.friction_share(spec))
        mmb, axes = _world_model(mm, fields, jnp.arange(nb))
        step = jax.vmap(mjx.step, in_axes=(axes, 0))
        ctrl0 = jnp.asarray(spec.stand_ctrl, jnp.float32)
        d0 = (dw if warp else mjx.make_data(mm)).replace(ctrl=ctrl0)
        data = jax.vmap(lambda m_, q: mjx.forward(m_, d0.replace(qpos=q)), in_axes=(axes, 0))(
            mmb, qpos0)
        mp = None
        if mlim is not None:
            mp = ql.motor_params(servo_fields, spec, dofs, model.actuator_ctrlrange,
                                 stall_scale, speed_scale)
            mp = ql.MotorParams(*(jnp.broadcast_to(jnp.asarray(x, jnp.float32), (nb, nu))
                                  for x in mp))

        def physics(dd, peak):
            """One physics step to the target ``dd.ctrl``; ``peak``: the largest motor
            current so far as a fraction of the limit (the gait rollouts' currents)."""
            q0, v0 = dd.qpos[:, qadr], dd.qvel[:, dofs]
            if st.limits:
                tau = ql.motor_torque(q0, v0, dd.ctrl, mp, mlim)
                dn = step(mmb, dd.replace(ctrl=tau)).replace(ctrl=dd.ctrl)
                qd = v0
            else:
                dn = step(mmb, dd)
                if mlim is None:
                    return dn, peak
                qd = dn.qvel[:, dofs]
                tau = ql.drive_torque(q0, qd, dd.ctrl, mp)
            frac = jnp.abs(mo.current(tau, qd, mlim)) / jnp.asarray(mlim.i_limit, tau.dtype)
            return dn, jnp.maximum(peak, jnp.max(frac, -1))

        z = jnp.zeros((nb,), jnp.float32)
        zi = jnp.zeros((nb,), jnp.int32)
        cs = {
            "seg": zi, "mode": zi, "started": jnp.zeros((nb,), bool),
            "last_mode": zi, "last_steer": z, "last_step": jnp.ones((nb,), jnp.float32),
            "p_old": jnp.zeros((nb, len(PARAM_NAMES)), jnp.float32),
            "p_new": jnp.zeros((nb, len(PARAM_NAMES)), jnp.float32),
            "alpha": jnp.ones((nb,), jnp.float32), "frac": z, "cyc": zi,
            "need": jnp.ones((nb,), bool),
            "ysin": z, "ycos": z, "ycount": zi, "switches": zi,
            "dec": jnp.zeros((nb, 6), jnp.float32), "ndec": zi, "cell": zi - 1,
        }
        stats = {
            "active": jnp.ones((nb,), bool), "closest": jnp.full((nb,), st.distmax),
            "closest_obstacle": jnp.full((nb,), -1, jnp.int32),
            "contact_step": jnp.full((nb,), -1, jnp.int32),
            "contact_obstacle": jnp.full((nb,), -1, jnp.int32),
            "fall_step": jnp.full((nb,), -1, jnp.int32),
            "reach_step": jnp.full((nb,), -1, jnp.int32),
            "end_step": jnp.full((nb,), st.n_steps, jnp.int32),
            "end_pose": jnp.zeros((nb, 3), jnp.float32),
            "mode_steps": jnp.zeros((nb, 3), jnp.int32),
            "cell_steps": jnp.zeros((nb, max(n_cells, 1)), jnp.int32),
            "peak_current": z,
        }
        hist = jnp.zeros((nb, lat_max, nu), jnp.float32)

        def decide(s, pos, k):
            yaw = jnp.where(s["ycount"] > 0, jnp.arctan2(s["ysin"], s["ycos"]), heading0)
            seg, target = _track(route, s["seg"], pos, c)
            near = (jnp.linalg.norm(goal - pos) < c.lookahead) & (seg == last_seg)
            target = jnp.where(near, goal, target)
            error = _wrap(jnp.arctan2(target[1] - pos[1], target[0] - pos[0]) - yaw)
            mode, steer, stp = _choose_near(error, s["mode"], near, c)
            if c.bend_distance > 0:
                stp = jnp.where(mode == 0, jnp.minimum(stp, _bend_cap(route, seg, pos, c)), stp)
            if c.start_ramp_s > 0:
                stp = jnp.where(mode == 0, jnp.minimum(stp, _start_cap(k * dt, c)), stp)
            hold = (k < ramp_steps) & s["started"]
            mode = jnp.where(hold, s["last_mode"], mode)
            steer = jnp.where(hold, s["last_steer"], steer)
            stp = jnp.where(hold, s["last_step"], stp)
            params = lib[mode]
            fwd = mode == 0
            params = params.at[TURN].set(jnp.where(fwd, steer, params[TURN]))
            params = params.at[STEP].set(jnp.where(fwd, params[STEP] * stp, params[STEP]))
            cell = jnp.int32(-1)
            if n_cells:
                cell = jnp.where(fwd, pick(stp), -1).astype(jnp.int32)
                params = jnp.where(fwd, cells[jnp.maximum(cell, 0)].at[TURN].set(steer), params)
            a = s["alpha"]
            p_old = jnp.where(s["started"], (1 - a) * s["p_old"] + a * s["p_new"], params)
            alpha = jnp.where(s["started"], 0.0, a)
            return {**s, "seg": seg, "mode": mode, "started": jnp.bool_(True), "cell": cell,
                    "last_mode": mode, "last_steer": steer, "last_step": stp,
                    "p_old": p_old, "p_new": params, "alpha": alpha,
                    "cyc": jnp.int32(0), "need": jnp.bool_(False),
                    "ysin": jnp.float32(0), "ycos": jnp.float32(0), "ycount": jnp.int32(0),
                    "switches": s["switches"] + (mode != s["mode"]).astype(jnp.int32),
                    "dec": jnp.stack([jnp.float32(k * dt), seg.astype(jnp.float32),
                                      error, mode.astype(jnp.float32), steer, stp]),
                    "ndec": s["ndec"] + 1}

        def engine(s, k):
            """The blended parameters and the engine time of control step ``k``."""
            p = (1 - s["alpha"]) * s["p_old"] + s["alpha"] * s["p_new"]
            period = p[PERIOD]
            m_ramp = jnp.ceil(RAMP_TIME / period) + 1
            t_eng = jnp.where(k < ramp_steps, k * dt,
                              (m_ramp + jnp.mod(s["frac"], 1.0)) * period)
            return p, t_eng

        def advance(s, pos, k):
            """One control step of one world's controller: its parameters and engine time."""
            s = jax.tree.map(lambda new, old: jnp.where(s["need"], new, old),
                             decide(s, pos, k), s)
            p, t_eng = engine(s, k)
            period = p[PERIOD]
            frac = s["frac"] + dt / period
            alpha = jnp.minimum(1.0, s["alpha"] + dt / (c.blend_cycles * s["p_new"][PERIOD]))
            cyc = s["cyc"] + 1
            done = frac >= 1.0 - PHASE_TOL
            need = done | (cyc >= wr.MAX_CYCLE_STEPS)
            frac = jnp.where(done, frac - 1.0, frac)
            return {**s, "frac": frac, "alpha": alpha, "cyc": cyc, "need": need}, p, t_eng

        targets_of = jax.vmap(lambda p, t: joint_targets(p, t, spec))

        def world_target(hist, k):
            """The coupled target each world sends at control step ``k`` from the engine's
            commands ``hist`` (last: step ``k``'s): latency, then target noise."""
            u = jnp.take_along_axis(hist, (lat_max - 1 - latency)[:, None, None], 1)[:, 0]
            noise = jax.random.normal(jax.random.fold_in(noise_key, k), (n_draw, nu),
                                      jnp.float32)
            return couple_controls(u + noise_std[:, None] * noise[noise_rows], spec)

        def control_step(carry, k):
            d, s, stt, hist = carry
            pos = d.qpos[:, :2]
            s, p, t_eng = jax.vmap(advance, in_axes=(0, 0, None))(s, pos, k)
            cmd = targets_of(p, t_eng)
            hist = jnp.where(k == 0, jnp.broadcast_to(cmd[:, None], hist.shape),
                             jnp.concatenate([hist[:, 1:], cmd[:, None]], 1))
            u = world_target(hist, k)
            on = (k >= push_start) & (k < push_stop)
            qfrc = jnp.zeros((nb, model.nv), jnp.float32).at[:, :3].set(
                jnp.where(on[:, None], push_force, 0.0))
            d = d.replace(ctrl=u, qfrc_applied=qfrc)
            if st.interpolate:
                # the next control step's target: the blend where it stands (a new cycle's
                # decision changes only what follows), after this step's latency and noise
                p_next, t_next = jax.vmap(engine, in_axes=(0, None))(s, k + 1)
                nxt = targets_of(p_next, t_next)
                u_next = world_target(jnp.concatenate([hist[:, 1:], nxt[:, None]], 1),
                                      jnp.minimum(k + 1, st.n_steps - 1))
                us = mo.physics_targets(u, u_next, sub, True)  # (nb, sub, nu)
                d, peak = jax.lax.fori_loop(
                    0, sub, lambda j, c_: physics(c_[0].replace(ctrl=us[:, j]), c_[1]),
                    (d, z))
            else:
                d, peak = jax.lax.fori_loop(0, sub, lambda _, c_: physics(*c_), (d, z))
            # observations after the step
            active = stt["active"] & (k < st.n_steps)
            q = d.qpos
            pos = q[:, :2]
            yaw = _yaw(q)
            s = {**s, "ysin": s["ysin"] + jnp.sin(yaw), "ycos": s["ycos"] + jnp.cos(yaw),
                 "ycount": s["ycount"] + 1}
            mode_steps = stt["mode_steps"] + (active[:, None] & (
                s["mode"][:, None] == jnp.arange(3))).astype(jnp.int32)
            cell_steps = stt["cell_steps"] + (active[:, None] & (
                s["cell"][:, None] == jnp.arange(max(n_cells, 1)))).astype(jnp.int32)
            dist = jax.vmap(lambda xp, xm: obstacle_distances(xp, xm, geoms, prisms,
                                                              st.distmax))(
                d.geom_xpos, d.geom_xmat)
            if dist.shape[1]:
                j = jnp.argmin(dist, 1).astype(jnp.int32)
                dj = jnp.min(dist, 1)
            else:
                j = jnp.full((nb,), -1, jnp.int32)
                dj = jnp.full((nb,), st.distmax)
            closer = active & (dj < stt["closest"])
            touch = active & (dj <= 0.0) & (stt["contact_step"] < 0)
            ground = jax.vmap(lambda xy: _ground(ramps, xy))(pos)
            height = q[:, 2] - ground
            up_z = 1.0 - 2.0 * (q[:, 4] ** 2 + q[:, 5] ** 2)
            fell = active & ((height < spec.fall_height) | (up_z < cos_tilt))
            reached = active & ~fell & (jnp.linalg.norm(goal - pos, axis=1) <= c.goal_radius)
            ends = fell | reached
            old = stt
            stt = {
                "active": active & ~ends,
                "closest": jnp.where(closer, dj, stt["closest"]),
                "closest_obstacle": jnp.where(closer, j, stt["closest_obstacle"]),
                "contact_step": jnp.where(touch, k, stt["contact_step"]),
                "contact_obstacle": jnp.where(touch, j, stt["contact_obstacle"]),
                "fall_step": jnp.where(fell, k, stt["fall_step"]),
                "reach_step": jnp.where(reached, k, stt["reach_step"]),
                "end_step": jnp.where(ends, k + 1, stt["end_step"]),
                "end_pose": jnp.where((ends | (active & (k == st.n_steps - 1)))[:, None],
                                      jnp.concatenate([pos, yaw[:, None]], 1),
                                      stt["end_pose"]),
                "mode_steps": mode_steps,
                "cell_steps": cell_steps,
                "peak_current": jnp.where(active, jnp.maximum(stt["peak_current"], peak),
                                          stt["peak_current"]),
            }
            if warp:
                stt = {**stt, "peak": jnp.maximum(old["peak"], jnp.stack(
                    [warp_pairs(d), jnp.max(d._impl.nefc)]))}
            return (d, s, stt, hist)

        if warp:
            stats["peak"] = jnp.zeros((2,), jnp.int32)
        traj0 = jnp.zeros((n_samples, nb, 4), jnp.float32)
        dec0 = jnp.zeros((n_samples, nb, 7), jnp.float32)

        def sample(state):
            i, carry, traj, decs = state
            carry = jax.lax.fori_loop(
                0, st.record_every,
                lambda j, cr: control_step(cr, i * st.record_every + j), carry)
            d, s, _, _ = carry
            row = jnp.concatenate([d.qpos[:, :2], _yaw(d.qpos)[:, None],
                                   s["mode"][:, None].astype(jnp.float32)], 1)
            traj = traj.at[i].set(row)
            decs = decs.at[i].set(jnp.concatenate(
                [s["dec"], s["ndec"][:, None].astype(jnp.float32)], 1))
            return i + 1, carry, traj, decs

        def more(state):
            i, (_, _, stt, _), _, _ = state
            return (i < n_samples) & jnp.any(stt["active"])

        state = (jnp.int32(0), (data, cs, stats, hist), traj0, dec0)
        n_done, (d, s, stt, _), traj, decs = jax.lax.while_loop(more, sample, state)
        if warp:
            jax.debug.callback(_warp_overflow, stt["peak"][0], stt["peak"][1], naconmax, njmax)
            stt = {k: v for k, v in stt.items() if k != "peak"}
        if not n_cells:
            stt = {k: v for k, v in stt.items() if k != "cell_steps"}
        return {**stt, "switches": s["switches"], "samples": n_done,
                "trajectory": jnp.swapaxes(traj, 0, 1), "decisions": jnp.swapaxes(decs, 0, 1)}

    return jax.jit(run, static_argnames=("n_draw",))


# --------------------------------------------------------------------------- records
def records(out: dict[str, np.ndarray], route: np.ndarray) -> list[dict[str, Any]]:
    """Each world's walk record with the native walker's fields
    (:func:`~eaco_jax.gait.walk_route.walk`)."""
    dt, every = float(out["dt"]), int(out["record_every"])
    goal = np.asarray(route, np.float64)[-1]
    n_done = int(out["samples"])
    recs = []
    for b in range(len(out["index"])):
        end = int(out["end_step"][b])
        t_end = end * dt
        reach = int(out["reach_step"][b])
        fall = int(out["fall_step"][b])
        contact = int(out["contact_step"][b])
        rows = []
        for i in range(n_done):
            step = (i + 1) * every
            if step > end:
                break
            x, y, yaw, mode = (float(v) for v in out["trajectory"][b, i])
            rows.append([round(step * dt, 3), x, y, yaw, int(mode)])
        ex, ey, eyaw = (float(v) for v in out["end_pose"][b])
        if not rows or rows[-1][0] != round(t_end, 3):
            mode = rows[-1][4] if rows else 0
            rows.append([round(t_end, 3), ex, ey, eyaw, mode])
        closest = float(out["closest"][b])
        reached = reach >= 0
        xy = np.asarray([r[1:3] for r in rows])
        recs.append({
            "motors": str(out.get("motors", "servo")),
            "success": bool(reached and contact < 0 and fall < 0),
            "reached": reached,
            "reach_time_s": (reach + 1) * dt if reached else None,
            "fell": fall >= 0,
            "fall_time_s": (fall + 1) * dt if fall >= 0 else None,
            "contact": contact >= 0,
            "contact_time_s": (contact + 1) * dt if contact >= 0 else None,
            "contact_obstacle": int(out["contact_obstacle"][b]) if contact >= 0 else None,
            "closest_approach_m": closest,
            "closest_obstacle": (int(out["closest_obstacle"][b])
                                 if closest < float(out["distmax"]) else None),
            "goal_distance_m": float(np.linalg.norm(goal - np.array([ex, ey]))),
            "walked_time_s": t_end,
            "walked_length_m": wr._length(xy),
            "mode_seconds": {m: round(float(out["mode_steps"][b, i]) * dt, 3)
                             for i, m in enumerate(wr.MODES)},
            "gait_switches": int(out["switches"][b]),
            "cell_seconds": ([round(float(v) * dt, 3) for v in out["cell_steps"][b]]
                             if "cell_steps" in out else None),
            "peak_current_frac": (float(out["peak_current"][b]) if out.get("has_currents")
                                  else None),
            "trajectory_columns": ["t", "x", "y", "yaw", "mode"],
            "trajectory": rows,
        })
    return recs


def decisions(out: dict[str, np.ndarray], b: int = 0) -> list[tuple]:
    """World ``b``'s step-cycle decisions ``(t, segment, heading error, mode, steer, step)``
    as the native walker's ``decisions`` list (from the per-sample records)."""
    seen, rows = 0, []
    for i in range(int(out["samples"])):
        t, seg, err, mode, steer, step, n = (float(v) for v in out["decisions"][b, i])
        if int(n) > seen:
            seen = int(n)
            rows.append((round(t, 3), int(seg), err, wr.MODES[int(mode)], steer, step))
    return rows


__all__ = ["WalkBatch", "check_impl", "decisions", "nominal_batch", "obstacle_distances", "records",
           "walk_batch", "with_nominal", "world_batch"]
