"""Scenes for a walking robot, and routes that minimise walking time (paper §5, issue #32).

A **scene** is a rectangular floor with prism obstacles (a convex footprint polygon and a
height) and ramps (a convex region of ground inclined by ``slope_deg`` rising towards
``uphill_deg``), a start, a goal and the robot's clearance. It is read from a small JSON file
(data only, :func:`load_scene`); ``"default"`` is the shipped ten-obstacle scene with a ramp and
:func:`random_scene` draws new ones from a seed.

The **cost** of a route (a polyline start -> goal) is the time a walking robot needs: each
straight segment is split where it crosses a ramp boundary; a piece of length ``l`` on ground
whose slope along the walking direction is ``s`` takes ``l / cos(s) / v(s)``, with ``v`` the gait
table's speed at that slope (linear between its rows); at every waypoint the robot turns on the
spot through the heading change at the table's yaw rate (and at the start, from
``start_heading_deg`` if the scene gives one). The planner treats a ramp as inclined ground;
its sides are not walls.

The **yardstick** (:func:`time_optimal_route`) is exact over *visibility-graph routes*: polylines
whose inner vertices are the obstacle corners grown by the clearance and the ramp polygons'
corners and edge points (``ramp_edge_points`` evenly spaced per edge), joined by segments that
stay clear of every obstacle. Over these routes Dijkstra on (previous vertex, vertex) states
prices every turn exactly. On a floor without ramps the shortest-time route bends only at grown
corners, so there it is the optimum over all polylines with corners; a ramp's time-optimal
crossing can bend anywhere on its boundary, which the edge points only sample.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.path_planning import GOAL, START, _point_inside, _segments_hit, grow

Array = jax.Array
Poly = tuple[tuple[float, float], ...]

DEFAULT_SPEEDS = "nao"


# --------------------------------------------------------------------------- gait speed table
@dataclasses.dataclass(frozen=True)
class GaitSpeeds:
    """Walking speed against ground slope, and the on-the-spot turning rate, of a gait library.

    ``slopes_deg`` ascend; ``speeds_mps[i]`` is the speed on ground rising ``slopes_deg[i]``
    along the walking direction; ``claims[i]`` the claim id of a measured row or ``""`` for a
    placeholder. Slopes outside the table are refused (no gait is known to walk them).
    """

    slopes_deg: tuple[float, ...]
    speeds_mps: tuple[float, ...]
    yaw_rate_deg_s: float
    claims: tuple[str, ...] = ()
    yaw_claim: str = ""
    source: str = ""

    def speed(self, slope_deg: np.ndarray) -> np.ndarray:
        """Speed [m/s] at ``slope_deg`` (linear between rows)."""
        return np.interp(slope_deg, self.slopes_deg, self.speeds_mps)

    @property
    def yaw_rate(self) -> float:
        """Turning rate [rad/s]."""
        return math.radians(self.yaw_rate_deg_s)

    @property
    def max_speed(self) -> float:
        return float(max(self.speeds_mps))


def load_gait_speeds(name_or_path: str | Path = DEFAULT_SPEEDS) -> GaitSpeeds:
    """The gait speed table: a shipped name (``eaco_jax/data/gait_speeds/<name>.json``) or a
    JSON file with ``rows`` (``slope_deg``, ``speed_mps``, ``claim``) and ``turn``
    (``yaw_rate_deg_s``, ``claim``)."""
    path = Path(name_or_path)
    if path.suffix != ".json":
        path = Path(str(resources.files("eaco_jax") / "data" / "gait_speeds" / f"{path}.json"))
    data = _read_json(path, "gait speed table")
    try:
        rows = sorted(data["rows"], key=lambda r: float(r["slope_deg"]))
        table = GaitSpeeds(
            slopes_deg=tuple(float(r["slope_deg"]) for r in rows),
            speeds_mps=tuple(float(r["speed_mps"]) for r in rows),
            claims=tuple(str(r.get("claim", "")) for r in rows),
            yaw_rate_deg_s=float(data["turn"]["yaw_rate_deg_s"]),
            yaw_claim=str(data["turn"].get("claim", "")),
            source=str(data.get("source", "")),
        )
    except (KeyError, TypeError, ValueError) as err:
        raise ProblemError(f"{path}: gait speed table needs rows of slope_deg/speed_mps and "
                           f"turn.yaw_rate_deg_s ({type(err).__name__}: {err})") from None
    if (not table.speeds_mps or min(table.speeds_mps) <= 0 or table.yaw_rate_deg_s <= 0
            or 0.0 not in table.slopes_deg):
        raise ProblemError(f"{path}: gait speed table needs positive speeds and yaw rate and "
                           "a row at slope 0")
    return table


# --------------------------------------------------------------------------- scene data
@dataclasses.dataclass(frozen=True)
class Obstacle:
    """A prism: convex footprint (counter-clockwise) and height [m]."""

    polygon: Poly
    height: float


@dataclasses.dataclass(frozen=True)
class Ramp:
    """A convex region of inclined ground, rising ``slope_deg`` towards heading ``uphill_deg``."""

    polygon: Poly
    slope_deg: float
    uphill_deg: float = 0.0


@dataclasses.dataclass(frozen=True)
class Scene:
    """A floor ``bounds = (xmin, ymin, xmax, ymax)`` [m] with obstacles, ramps, start and goal."""

    name: str
    bounds: tuple[float, float, float, float]
    start: tuple[float, float]
    goal: tuple[float, float]
    obstacles: tuple[Obstacle, ...] = ()
    ramps: tuple[Ramp, ...] = ()
    clearance: float = 0.15
    start_heading_deg: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The scene as the JSON data :func:`scene_from_dict` reads."""
        return {
            "name": self.name, "bounds": list(self.bounds), "start": list(self.start),
            "goal": list(self.goal), "clearance": self.clearance,
            "start_heading_deg": self.start_heading_deg,
            "obstacles": [{"polygon": [list(v) for v in o.polygon], "height": o.height}
                          for o in self.obstacles],
            "ramps": [{"polygon": [list(v) for v in r.polygon], "slope_deg": r.slope_deg,
                       "uphill_deg": r.uphill_deg} for r in self.ramps],
        }


def _read_json(path: Path, what: str) -> Any:
    try:
        text = path.read_text()
    except OSError as err:
        raise ProblemError(f"cannot read {what} {path}: {err.strerror or err}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise ProblemError(f"{path}: not valid JSON ({err.msg} at line {err.lineno}); "
                           f"fix the {what} file") from None


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _segments_cross(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> bool:
    """Whether two closed segments share a point."""
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0 not in (d1, d2, d3, d4):
        return True

    def on(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: float) -> bool:
        return abs(d) < 1e-12 and min(a[0], b[0]) - 1e-12 <= c[0] <= max(a[0], b[0]) + 1e-12 \
            and min(a[1], b[1]) - 1e-12 <= c[1] <= max(a[1], b[1]) + 1e-12

    return on(q1, q2, p1, d1) or on(q1, q2, p2, d2) or on(p1, p2, q1, d3) or on(p1, p2, q2, d4)


def check_polygon(poly: Any, what: str) -> Poly:
    """A simple, convex polygon of >= 3 finite vertices, returned counter-clockwise."""
    try:
        p = np.asarray(poly, dtype=np.float64)
    except (TypeError, ValueError):
        raise ProblemError(f"{what}: polygon must be a list of [x, y] vertices") from None
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or not np.all(np.isfinite(p)):
        raise ProblemError(f"{what}: polygon needs >= 3 finite [x, y] vertices, got shape "
                           f"{p.shape}")
    k = len(p)
    for i in range(k):
        for j in range(i + 1, k):
            if j == i + 1 or (i == 0 and j == k - 1):
                if np.allclose(p[i], p[j]):
                    raise ProblemError(f"{what}: polygon is not simple (vertices {i} and {j} "
                                       "coincide); list each corner once")
                continue
            if _segments_cross(p[i], p[(i + 1) % k], p[j], p[(j + 1) % k]):
                raise ProblemError(f"{what}: polygon is not simple (edges {i} and {j} cross); "
                                   "list its corners in order around it")
    area2 = float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
    if abs(area2) < 1e-12:
        raise ProblemError(f"{what}: polygon has zero area")
    if area2 < 0:
        p = p[::-1]
    e = np.roll(p, -1, axis=0) - p
    turn = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    if np.any(turn < -1e-12):
        raise ProblemError(f"{what}: polygon is not convex; split it into convex parts")
    return tuple((float(x), float(y)) for x, y in p)


def _convex_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex polygons' interiors overlap (separating-axis test)."""
    for poly in (a, b):
        e = np.roll(poly, -1, axis=0) - poly
        for n in np.stack([e[:, 1], -e[:, 0]], axis=1):
            pa, pb = a @ n, b @ n
            if pa.max() <= pb.min() + 1e-12 or pb.max() <= pa.min() + 1e-12:
                return False
    return True


def _number(value: Any, what: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ProblemError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ProblemError(f"{what} must be finite, got {value!r}")
    return out


def _point(value: Any, what: str) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ProblemError(f"{what} must be [x, y], got {value!r}")
    return (_number(value[0], f"{what}[0]"), _number(value[1], f"{what}[1]"))


def scene_from_dict(data: Any, where: str = "scene") -> Scene:
    """Check and build a :class:`Scene` from JSON data (one ProblemError line per fault)."""
    if not isinstance(data, dict):
        raise ProblemError(f"{where}: expected a JSON object with bounds, start, goal, "
                           f"obstacles, ramps; got {type(data).__name__}")
    known = {"name", "bounds", "start", "goal", "obstacles", "ramps", "clearance",
             "start_heading_deg", "note"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ProblemError(f"{where}: unknown key {unknown[0]!r} "
                           f"(keys: {', '.join(sorted(known))})")
    for key in ("bounds", "start", "goal"):
        if key not in data:
            raise ProblemError(f"{where}: missing {key!r}")
    b = data["bounds"]
    if not isinstance(b, (list, tuple)) or len(b) != 4:
        raise ProblemError(f"{where}: bounds must be [xmin, ymin, xmax, ymax], got {b!r}")
    bounds = tuple(_number(v, f"{where}: bounds[{i}]") for i, v in enumerate(b))
    if not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
        raise ProblemError(f"{where}: bounds {list(bounds)} need xmin < xmax and ymin < ymax")
    obstacles = []
    for i, o in enumerate(data.get("obstacles") or []):
        if not isinstance(o, dict) or "polygon" not in o:
            raise ProblemError(f"{where}: obstacle {i} must be an object with polygon, height")
        h = _number(o.get("height", 1.0), f"{where}: obstacle {i} height")
        if h <= 0:
            raise ProblemError(f"{where}: obstacle {i} height must be > 0, got {h}")
        obstacles.append(Obstacle(check_polygon(o["polygon"], f"{where}: obstacle {i}"), h))
    ramps = []
    for i, r in enumerate(data.get("ramps") or []):
        if not isinstance(r, dict) or "polygon" not in r or "slope_deg" not in r:
            raise ProblemError(f"{where}: ramp {i} must be an object with polygon, slope_deg, "
                               "uphill_deg")
        ramps.append(Ramp(check_polygon(r["polygon"], f"{where}: ramp {i}"),
                          _number(r["slope_deg"], f"{where}: ramp {i} slope_deg"),
                          _number(r.get("uphill_deg", 0.0), f"{where}: ramp {i} uphill_deg")))
    clearance = _number(data.get("clearance", 0.15), f"{where}: clearance")
    if clearance < 0:
        raise ProblemError(f"{where}: clearance must be >= 0, got {clearance}")
    heading = data.get("start_heading_deg")
    return Scene(
        name=str(data.get("name", "scene")), bounds=bounds,  # type: ignore[arg-type]
        start=_point(data["start"], f"{where}: start"), goal=_point(data["goal"], f"{where}: goal"),
        obstacles=tuple(obstacles), ramps=tuple(ramps), clearance=clearance,
        start_heading_deg=None if heading is None else _number(heading,
                                                               f"{where}: start_heading_deg"))


def load_scene(name_or_path: str | Path) -> Scene:
    """A scene from a JSON file, ``"default"`` (the shipped scene) or ``"random:SEED"``."""
    text = str(name_or_path)
    if text.startswith("random:"):
        try:
            seed = int(text.split(":", 1)[1])
        except ValueError:
            raise ProblemError(f"scene {text!r}: write random:SEED with an integer seed") from None
        return random_scene(seed)
    if text == "default":
        path = Path(str(resources.files("eaco_jax") / "data" / "scenes" / "default.json"))
    else:
        path = Path(text)
        if not path.is_file():
            raise ProblemError(f"scene {text!r} is not a file; give a scene JSON file, "
                               "'default' or 'random:SEED'")
    return scene_from_dict(_read_json(path, "scene"), where=str(path))


# --------------------------------------------------------------------------- geometry
def _clip(a: np.ndarray, b: np.ndarray, poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For segments a[k] -> b[k], the parameter interval [t0, t1] inside a convex CCW polygon
    (t0 >= t1 where the segment misses it)."""
    e = np.roll(poly, -1, axis=0) - poly
    normals = np.stack([e[:, 1], -e[:, 0]], axis=1)
    d = b - a
    num = np.einsum("ej,ekj->ke", normals, poly[:, None, :] - a[None, :, :])
    den = d @ normals.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / den
    t0 = np.max(np.where(den < 0, t, 0.0), axis=1, initial=0.0)
    t1 = np.min(np.where(den > 0, t, 1.0), axis=1, initial=1.0)
    outside = np.any((den == 0) & (num < 0), axis=1)
    return t0, np.where(outside, t0, t1)


def segment_times(a: np.ndarray, b: np.ndarray, ramps: Sequence[Ramp],
                  speeds: GaitSpeeds) -> np.ndarray:
    """Walking time [s] of each straight segment a[k] -> b[k] over flat ground and ramps."""
    d = b - a
    length = np.linalg.norm(d, axis=1)
    unit = d / np.maximum(length, 1e-300)[:, None]
    flat = np.ones(len(a))
    time = np.zeros(len(a))
    for r in ramps:
        t0, t1 = _clip(a, b, np.asarray(r.polygon))
        frac = np.clip(t1 - t0, 0.0, 1.0)
        flat -= frac
        up = np.array([math.cos(math.radians(r.uphill_deg)), math.sin(math.radians(r.uphill_deg))])
        slope = np.arctan(math.tan(math.radians(r.slope_deg)) * (unit @ up))
        time += frac * length / np.cos(slope) / speeds.speed(np.degrees(slope))
    return time + np.clip(flat, 0.0, 1.0) * length / speeds.speed(0.0)


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


# --------------------------------------------------------------------------- the problem
@struct.dataclass
class ScenePath:
    """Visibility-graph routes through a scene, costed in walking time (``kind = "path"``).

    A solution is a node sequence of fixed length ``n`` as in
    :class:`~eaco_jax.problems.path_planning.PathPlanning` (start first, the goal once reached
    and then repeated); its cost is the walking time [s], +inf for a blocked edge or a sequence
    that never reaches the goal. ``step_cost``/``goal_cost`` are what the colony's heuristic
    reads (edge times and a lower bound on the time left to the goal).
    """

    coords: Array  # (n, 2) start, goal, grown obstacle corners, ramp points
    dist: Array  # (n, n) segment lengths [m], +inf where blocked or i == j
    to_goal: Array  # (n,) straight-line distance to the goal [m]
    time: Array  # (n, n) walking time of each directed segment [s], +inf where blocked
    heading: Array  # (n, n) heading of segment i -> j [rad]
    yaw_rate: Array  # () turning rate [rad/s]
    start_heading: Array  # () heading at the start [rad]; NaN: free
    scene: Scene | None = struct.field(pytree_node=False, default=None)
    name: str = struct.field(pytree_node=False, default="scene")
    optimum: float | None = struct.field(pytree_node=False, default=None)
    optimal_route: tuple[int, ...] = struct.field(pytree_node=False, default=())

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
    def step_cost(self) -> Array:
        return self.time

    @property
    def goal_cost(self) -> Array:
        """A lower bound on the time from each node to the goal: straight at top speed."""
        fastest = jnp.min(jnp.where(jnp.isfinite(self.time), self.time / self.dist, jnp.inf))
        return self.to_goal * fastest

    def evaluate(self, paths: Array) -> Array:
        """(m,) walking times [s] of node sequences (m, n); +inf if blocked or unfinished."""
        if paths.ndim != 2 or paths.shape[1] != self.n:
            raise ProblemError(f"paths must be (ants, {self.n}), got {tuple(paths.shape)}")
        return jax.vmap(self._one)(paths).astype(jnp.float32)

    def _one(self, path: Array) -> Array:
        a, b = path[:-1], path[1:]
        moves = a != b
        walk = jnp.where(moves, self.time[a, b], 0.0).sum()
        h = self.heading[a, b]
        k = jnp.arange(a.shape[0])
        last = jax.lax.cummax(jnp.where(moves, k, -1))  # latest move at or before k
        prev = jnp.concatenate([jnp.array([-1]), last[:-1]])  # latest move before k
        h_prev = jnp.where(prev >= 0, h[jnp.maximum(prev, 0)], self.start_heading)
        turn = jnp.abs((h - h_prev + jnp.pi) % (2 * jnp.pi) - jnp.pi)
        turn = jnp.where(moves & ~jnp.isnan(h_prev), turn, 0.0).sum()
        ok = (path[0] == START) & (path[-1] == GOAL)
        return jnp.where(ok, walk + turn / self.yaw_rate, jnp.inf)

    def waypoints(self, path: np.ndarray) -> np.ndarray:
        """(k, 2) coordinates of a path from start to its first arrival at the goal."""
        path = np.asarray(path)
        end = int(np.argmax(path == GOAL)) if np.any(path == GOAL) else len(path) - 1
        keep = np.concatenate([[True], path[1: end + 1] != path[:end]])
        return np.asarray(self.coords)[path[: end + 1][keep]]

    def route(self, nodes: Sequence[int]) -> np.ndarray:
        """A route given as node ids, as the fixed-length solution ``evaluate`` takes."""
        out = np.full(self.n, GOAL, np.int32)
        out[: len(nodes)] = nodes
        return out


def time_optimal_route(time: np.ndarray, heading: np.ndarray, yaw_rate: float,
                       start_heading: float | None = None) -> tuple[float, list[int]]:
    """Exact least-time route START -> GOAL over the graph ``time`` (+inf: no edge), with a
    turn of ``|heading change| / yaw_rate`` at every inner vertex (and at the start when
    ``start_heading`` is given): Dijkstra over directed-edge states (i -> j), whose
    transitions (i -> j) -> (j -> k) cost ``time[j, k]`` plus the turn at j."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    n = len(time)
    ok = np.isfinite(time)
    ok[GOAL, :] = False  # the route ends at the goal
    ei, ej = np.nonzero(ok)
    e = len(ei)
    eid = np.full((n, n), -1)
    eid[ei, ej] = np.arange(e)
    rows, cols, wts = [], [], []
    for j in range(n):
        inc = np.flatnonzero(ok[:, j])
        out = np.flatnonzero(ok[j])
        if len(inc) == 0 or len(out) == 0:
            continue
        turn = np.abs(_wrap(heading[j, out][None, :] - heading[inc, j][:, None]))
        w = time[j, out][None, :] + turn / yaw_rate
        rows.append(np.repeat(eid[inc, j], len(out)))
        cols.append(np.tile(eid[j, out], len(inc)))
        wts.append(w.reshape(-1))
    out = np.flatnonzero(ok[START])
    first = time[START, out].copy()
    if start_heading is not None:
        first += np.abs(_wrap(heading[START, out] - start_heading)) / yaw_rate
    rows.append(np.full(len(out), e))  # the source state
    cols.append(eid[START, out])
    wts.append(first)
    graph = csr_matrix((np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(e + 1, e + 1))
    d, pred = dijkstra(graph, directed=True, indices=e, return_predecessors=True)
    ends = eid[:, GOAL][eid[:, GOAL] >= 0]
    if len(ends) == 0 or not np.any(np.isfinite(d[ends])):
        return math.inf, []
    best = int(ends[np.argmin(d[ends])])
    route = [GOAL]
    s = best
    while s != e:
        route.append(int(ei[s]))
        s = int(pred[s])
    return float(d[best]), route[::-1]


def build_problem(scene: Scene, speeds: GaitSpeeds | None = None, *,
                  ramp_edge_points: int = 2, pad_to: int | None = None) -> ScenePath:
    """The scene's visibility graph costed in walking time, with its exact optimum.

    Nodes: start, goal, the obstacle corners grown by the clearance and the ramps' corners
    plus ``ramp_edge_points`` evenly spaced points per ramp edge (those on the floor and clear of
    every obstacle). ``pad_to`` adds unreachable nodes up to that many, so scenes share shapes.
    """
    speeds = speeds or load_gait_speeds()
    lo, hi = min(speeds.slopes_deg), max(speeds.slopes_deg)
    for i, r in enumerate(scene.ramps):
        if abs(r.slope_deg) > min(hi, -lo):
            raise ProblemError(f"{scene.name}: ramp {i} slope {r.slope_deg:g} deg is outside the "
                               f"gait table's {lo:g}..{hi:g} deg; no gait is known to walk it")
    for i, r in enumerate(scene.ramps):
        for j in range(i):
            if _convex_overlap(np.asarray(r.polygon), np.asarray(scene.ramps[j].polygon)):
                raise ProblemError(f"{scene.name}: ramps {j} and {i} overlap; ground has one "
                                   "slope at a point")
    c = scene.clearance
    polys = [np.asarray(o.polygon) for o in scene.obstacles]
    grown = [grow(p, c) for p in polys]
    solid = [grow(p, 0.999 * c) if c > 0 else p for p in polys]
    xmin, ymin, xmax, ymax = scene.bounds

    def on_floor(p: np.ndarray) -> np.ndarray:
        return (p[..., 0] >= xmin) & (p[..., 0] <= xmax) & (p[..., 1] >= ymin) & (p[..., 1] <= ymax)

    s, g = np.asarray(scene.start), np.asarray(scene.goal)
    for label, p in (("start", s), ("goal", g)):
        at = f"({p[0]:g}, {p[1]:g})"
        if not on_floor(p):
            raise ProblemError(f"{scene.name}: {label} {at} is off the floor "
                               f"{list(scene.bounds)}; move it onto the floor")
        for i, poly in enumerate(solid):
            if _point_inside(p, poly):
                raise ProblemError(f"{scene.name}: {label} {at} lies on obstacle {i} "
                                   f"(grown by the clearance {c:g} m); move it or the obstacle")
    pts = [*grown]
    for r in scene.ramps:
        rp = np.asarray(r.polygon)
        nxt = np.roll(rp, -1, axis=0)
        u = np.arange(ramp_edge_points + 1) / (ramp_edge_points + 1)
        pts.append((rp[:, None, :] + u[None, :, None] * (nxt - rp)[:, None, :]).reshape(-1, 2))
    verts = np.concatenate(pts) if pts else np.zeros((0, 2))
    keep = on_floor(verts) & np.array([not any(_point_inside(v, poly) for poly in solid)
                                       for v in verts], bool)
    coords = np.concatenate([s[None], g[None], verts[keep]])
    _, first = np.unique(np.round(coords, 9), axis=0, return_index=True)
    coords = coords[np.sort(first)]
    if np.allclose(coords[0], g):
        raise ProblemError(f"{scene.name}: start and goal coincide")
    n = len(coords)
    i, j = np.nonzero(~np.eye(n, dtype=bool))
    blocked = np.zeros(len(i), bool)
    for poly in solid:
        blocked |= _segments_hit(coords[i], coords[j], poly)
    free_i, free_j = i[~blocked], j[~blocked]
    dist = np.full((n, n), np.inf)
    dist[free_i, free_j] = np.linalg.norm(coords[free_i] - coords[free_j], axis=1)
    time = np.full((n, n), np.inf)
    time[free_i, free_j] = segment_times(coords[free_i], coords[free_j], scene.ramps, speeds)
    delta = coords[None, :, :] - coords[:, None, :]
    heading = np.arctan2(delta[..., 1], delta[..., 0])
    start_heading = (None if scene.start_heading_deg is None
                     else math.radians(scene.start_heading_deg))
    optimum, route = time_optimal_route(time, heading, speeds.yaw_rate, start_heading)
    if not math.isfinite(optimum):
        raise ProblemError(f"{scene.name}: the goal cannot be reached from the start around "
                           "these obstacles; move an obstacle or lower the clearance")
    if pad_to is not None:
        if pad_to < n:
            raise ProblemError(f"{scene.name}: {n} graph nodes do not fit pad_to={pad_to}")
        extra = pad_to - n
        coords = np.concatenate([coords, np.repeat(coords[:1], extra, axis=0)])
        dist, time, heading = (np.pad(m, ((0, extra), (0, extra)), constant_values=v)
                               for m, v in ((dist, np.inf), (time, np.inf), (heading, 0.0)))
    return ScenePath(
        coords=jnp.asarray(coords, jnp.float32),
        dist=jnp.asarray(dist, jnp.float32),
        to_goal=jnp.asarray(np.linalg.norm(coords - g, axis=1), jnp.float32),
        time=jnp.asarray(time, jnp.float32),
        heading=jnp.asarray(heading, jnp.float32),
        yaw_rate=jnp.asarray(speeds.yaw_rate, jnp.float32),
        start_heading=jnp.asarray(np.nan if start_heading is None else start_heading,
                                  jnp.float32),
        scene=scene, name=scene.name, optimum=optimum, optimal_route=tuple(route),
    )


# --------------------------------------------------------------------------- random scenes
def random_scene(seed: int, num_obstacles: int = 10, *, size: float = 10.0,
                 ramp: bool = True, clearance: float = 0.15) -> Scene:
    """A square floor of side ``size`` [m]: start near the lower-left and goal near the upper-right
    corner, a rectangular ramp (slope +-5 deg, random direction) and ``num_obstacles`` convex
    prisms around the diagonal clear of it, all reproducible from ``seed``."""
    if num_obstacles < 0:
        raise ProblemError(f"num_obstacles must be >= 0, got {num_obstacles}")
    rng = np.random.default_rng(seed)
    start, goal = np.array([0.05, 0.05]) * size, np.array([0.95, 0.95]) * size
    diag = (goal - start) / np.linalg.norm(goal - start)
    side = np.array([-diag[1], diag[0]])
    ramps: list[Ramp] = []
    taken: list[tuple[np.ndarray, float]] = []
    if ramp:
        c = start + rng.uniform(0.35, 0.65) * (goal - start) + rng.uniform(-0.1, 0.1) * size * side
        half = rng.uniform(0.08, 0.12, 2) * size
        ang = rng.uniform(0, 2 * np.pi)
        rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        box = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
        ramps.append(Ramp(check_polygon(c + box @ rot.T, "ramp"),
                          float(rng.choice([-5.0, 5.0])), float(np.degrees(ang))))
        taken.append((c, float(np.linalg.norm(half))))
    obstacles: list[Obstacle] = []
    tries = 0
    while len(obstacles) < num_obstacles:
        tries += 1
        if tries > 10_000:
            raise ProblemError(f"cannot place {num_obstacles} obstacles on a {size} m floor")
        r = rng.uniform(0.06, 0.12) * size
        c = start + rng.uniform(0.12, 0.88) * (goal - start) + rng.uniform(-0.3, 0.3) * size * side
        if min(np.linalg.norm(c - start), np.linalg.norm(c - goal)) < r + 2 * clearance + 0.05:
            continue
        if any(np.linalg.norm(c - c2) < r + r2 + 2 * clearance for c2, r2 in taken):
            continue
        k = int(rng.integers(3, 8))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        if np.max(np.diff(np.append(ang, ang[0] + 2 * np.pi))) > np.pi * 0.9:
            continue
        poly = c + r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        try:
            footprint = check_polygon(poly, "obstacle")
        except ProblemError:
            continue  # two corners (nearly) coincide: draw again
        obstacles.append(Obstacle(footprint, float(np.round(rng.uniform(0.3, 1.2), 3))))
        taken.append((c, r))
    return Scene(name=f"scene{num_obstacles}-seed{seed}", bounds=(0.0, 0.0, size, size),
                 start=tuple(start.tolist()), goal=tuple(goal.tolist()),  # type: ignore[arg-type]
                 obstacles=tuple(obstacles), ramps=tuple(ramps), clearance=clearance)


def scene_problem(name_or_path: str | Path = "default", **kwargs: Any) -> ScenePath:
    """:func:`load_scene` then :func:`build_problem` (the registry's ``scene`` factory)."""
    return build_problem(load_scene(name_or_path), **kwargs)
