"""Shortest collision-free walk from a start to a goal among polygonal obstacles (paper §5).

The paper's humanoid walks through ten polygonal obstacles; on the ground this is a 2-D
problem over the obstacles' footprints. We build the *visibility graph*: nodes are the start,
the goal and every obstacle vertex pushed outward by a clearance (the robot's radius), and an
edge joins two nodes when the straight segment between them stays out of every obstacle grown by
that clearance. Any shortest obstacle-avoiding path runs along this graph, so Dijkstra gives
the exact optimum - the yardstick for the colony.

A solution is a node sequence of fixed length ``n``: start first, the goal once reached and then
repeated (``kind = "path"``). Its cost is the Euclidean length; a sequence that uses a blocked
edge or never reaches the goal costs +inf.

Obstacles must be convex polygons (split a non-convex one into convex parts).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.ops.path_ops import GOAL, START
from eaco_jax.problems.base import ProblemError


def _outward_normals(poly: np.ndarray) -> np.ndarray:
    """Unit outward normals of a counter-clockwise convex polygon's edges (edge i: v_i -> v_i+1)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _as_ccw_convex(poly: Sequence[Sequence[float]], index: int) -> np.ndarray:
    p = np.asarray(poly, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or not np.all(np.isfinite(p)):
        raise ProblemError(f"obstacle {index}: needs >= 3 finite (x, y) vertices, got {p.shape}")
    area2 = np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if abs(area2) < 1e-12:
        raise ProblemError(f"obstacle {index}: polygon has zero area")
    if area2 < 0:
        p = p[::-1]
    e = np.roll(p, -1, axis=0) - p
    cross = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    if np.any(cross < -1e-12):
        raise ProblemError(
            f"obstacle {index} is not convex; split it into convex polygons")
    return p


def grow(poly: np.ndarray, clearance: float) -> np.ndarray:
    """Offset a convex CCW polygon outward by ``clearance`` (vertices along the corner bisector)."""
    normals = _outward_normals(poly)
    prev = np.roll(normals, 1, axis=0)  # normal of the edge ending at vertex i
    bis = normals + prev
    scale = clearance / (1.0 + np.sum(normals * prev, axis=1))
    return poly + bis * scale[:, None]


def _segments_hit(a: np.ndarray, b: np.ndarray, poly: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """For segments a[k] -> b[k], whether they pass through the interior of a convex polygon.

    Cyrus-Beck clipping: the segment's parameter interval inside every edge's half-plane;
    a positive-length remainder means it crosses the interior.
    """
    normals = _outward_normals(poly)  # (E, 2)
    d = b - a  # (K, 2)
    num = np.einsum("ej,ekj->ke", normals, poly[:, None, :] - a[None, :, :])  # (K, E)
    den = d @ normals.T  # (K, E)
    t_enter = np.zeros(len(a))
    t_leave = np.ones(len(a))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / den
    entering = den < -eps
    leaving = den > eps
    parallel_out = (~entering & ~leaving) & (num < eps)
    t_enter = np.max(np.where(entering, t, 0.0), axis=1, initial=0.0)
    t_leave = np.min(np.where(leaving, t, 1.0), axis=1, initial=1.0)
    inside = (t_leave - t_enter) * np.linalg.norm(d, axis=1) > 1e-7
    return inside & ~np.any(parallel_out, axis=1)


def _point_inside(p: np.ndarray, poly: np.ndarray) -> bool:
    normals = _outward_normals(poly)
    return bool(np.all(np.einsum("ej,ej->e", normals, p[None] - poly) < 0))


@struct.dataclass
class PathPlanning:
    """Visibility-graph path problem. ``dist[i, j]`` is +inf where the segment is blocked."""

    coords: jax.Array  # (n, 2) node positions: start, goal, grown obstacle vertices
    dist: jax.Array  # (n, n) float32 segment lengths, +inf where blocked or i == j
    to_goal: jax.Array  # (n,) straight-line distance to the goal (the heuristic's lower bound)
    obstacles: tuple = struct.field(pytree_node=False, default=())  # convex polygons (tuples)
    clearance: float = struct.field(pytree_node=False, default=0.0)
    name: str = struct.field(pytree_node=False, default="path")
    optimum: float | None = struct.field(pytree_node=False, default=None)

    kind: ClassVar[str] = "path"

    @property
    def n(self) -> int:
        return int(self.coords.shape[0])

    @property
    def start(self) -> int:
        return START

    @property
    def goal(self) -> int:
        return GOAL

    @property
    def step_cost(self) -> jax.Array:
        """Edge costs a path colony reads: the lengths."""
        return self.dist

    @property
    def goal_cost(self) -> jax.Array:
        """Lower bound on the cost from each node to the goal: the straight line."""
        return self.to_goal

    def evaluate(self, paths: jax.Array) -> jax.Array:
        """(m,) lengths of node sequences (m, n); +inf if blocked or the goal is not reached."""
        if paths.ndim != 2 or paths.shape[1] != self.n:
            raise ProblemError(f"paths must be (ants, {self.n}), got {tuple(paths.shape)}")
        a, b = paths[:, :-1], paths[:, 1:]
        step = jnp.where(a == b, 0.0, self.dist[a, b])
        ok = (paths[:, 0] == START) & (paths[:, -1] == GOAL)
        return jnp.where(ok, step.sum(axis=1), jnp.inf).astype(jnp.float32)

    def waypoints(self, path: np.ndarray) -> np.ndarray:
        """(k, 2) coordinates of a path from start to its first arrival at the goal."""
        path = np.asarray(path)
        end = int(np.argmax(path == GOAL)) if np.any(path == GOAL) else len(path) - 1
        return np.asarray(self.coords)[path[: end + 1]]

    @classmethod
    def from_obstacles(
        cls,
        obstacles: Sequence[Sequence[Sequence[float]]],
        start: Sequence[float],
        goal: Sequence[float],
        *,
        clearance: float = 0.1,
        name: str = "path",
    ) -> PathPlanning:
        """Build the visibility graph for convex ``obstacles`` and compute the exact optimum."""
        if not np.isfinite(clearance) or clearance < 0:
            raise ProblemError(f"clearance must be a finite number >= 0, got {clearance}")
        polys = [_as_ccw_convex(p, i) for i, p in enumerate(obstacles)]
        grown = [grow(p, clearance) for p in polys]
        # collision shapes slightly smaller than the node offsets, so edges that run along a
        # grown boundary (between two of its vertices) count as free
        solid = [grow(p, 0.999 * clearance) if clearance > 0 else p for p in polys]
        s, g = np.asarray(start, float), np.asarray(goal, float)
        for label, p in (("start", s), ("goal", g)):
            if p.shape != (2,) or not np.all(np.isfinite(p)):
                raise ProblemError(f"{label} must be a finite (x, y) point, got {p}")
            for i, poly in enumerate(solid):
                if _point_inside(p, poly):
                    raise ProblemError(f"{label} {tuple(p)} lies inside obstacle {i} "
                                       f"(grown by clearance {clearance})")
        verts = np.concatenate(grown) if grown else np.zeros((0, 2))
        keep = [not any(_point_inside(v, poly) for poly in solid) for v in verts]
        coords = np.concatenate([s[None], g[None], verts[np.asarray(keep, bool)]])
        n = len(coords)
        i, j = np.triu_indices(n, 1)
        blocked = np.zeros(len(i), bool)
        for poly in solid:
            blocked |= _segments_hit(coords[i], coords[j], poly)
        d = np.full((n, n), np.inf)
        length = np.linalg.norm(coords[i] - coords[j], axis=1)
        d[i[~blocked], j[~blocked]] = length[~blocked]
        d[j[~blocked], i[~blocked]] = length[~blocked]
        optimum = shortest_path_length(d)
        if not np.isfinite(optimum):
            raise ProblemError("the goal cannot be reached from the start around these obstacles")
        return cls(
            coords=jnp.asarray(coords, jnp.float32),
            dist=jnp.asarray(d, jnp.float32),
            to_goal=jnp.asarray(np.linalg.norm(coords - g, axis=1), jnp.float32),
            obstacles=tuple(tuple(map(tuple, p.tolist())) for p in polys),
            clearance=float(clearance),
            name=name,
            optimum=float(optimum),
        )


def shortest_path_length(dist: np.ndarray) -> float:
    """Exact start -> goal shortest path length on the visibility graph (Dijkstra)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    d = np.where(np.isfinite(dist), dist, 0.0)
    return float(dijkstra(csr_matrix(d), directed=False, indices=START)[GOAL])


def random_environment(
    num_obstacles: int = 10,
    *,
    seed: int = 0,
    size: float = 10.0,
    clearance: float = 0.15,
    radius: tuple[float, float] = (0.06, 0.12),
    name: str | None = None,
) -> PathPlanning:
    """A square world of side ``size`` with ``num_obstacles`` random convex polygons around the
    diagonal from a start at the lower-left to a goal at the upper-right corner (reproducible
    from ``seed``). Obstacle radii are drawn from ``radius`` (fractions of ``size``)."""
    if num_obstacles < 0:
        raise ProblemError(f"num_obstacles must be >= 0, got {num_obstacles}")
    rng = np.random.default_rng(seed)
    start, goal = np.array([0.05, 0.05]) * size, np.array([0.95, 0.95]) * size
    polys: list[np.ndarray] = []
    centres: list[tuple[np.ndarray, float]] = []
    tries = 0
    while len(polys) < num_obstacles:
        tries += 1
        if tries > 10_000:
            raise ProblemError(f"cannot place {num_obstacles} obstacles in a {size} world")
        r = rng.uniform(*radius) * size
        # centres in a band around the start-goal diagonal, so the obstacles are in the way
        u, v = rng.uniform(0.12, 0.88), rng.uniform(-0.3, 0.3) * size
        c = start + u * (goal - start) + v * np.array([-1.0, 1.0]) / np.sqrt(2.0)
        if min(np.linalg.norm(c - start), np.linalg.norm(c - goal)) < r + 2 * clearance + 0.05:
            continue
        if any(np.linalg.norm(c - c2) < r + r2 + 2 * clearance for c2, r2 in centres):
            continue
        k = int(rng.integers(3, 8))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        if np.max(np.diff(np.append(ang, ang[0] + 2 * np.pi))) > np.pi * 0.9:
            continue  # keep polygons reasonably round (no slivers)
        polys.append(c + r * np.stack([np.cos(ang), np.sin(ang)], axis=1))
        centres.append((c, r))
    return PathPlanning.from_obstacles(
        polys, start, goal, clearance=clearance,
        name=name or f"obstacles{num_obstacles}-seed{seed}")


def paper_environment() -> PathPlanning:
    """The default scenario: ten polygonal obstacles, as in the paper's Figs. 5-7."""
    return random_environment(10, seed=1, name="paper10")
