"""Closed-loop walking of a planned route through a scene on native MuJoCo (issue #32, item 4).

The robot stands at the route's start in the scene's model (:mod:`eaco_jax.gait.scene_world`)
and a path-following controller steers it along the route's polyline, one step cycle at a time:

* **Tracking** (:func:`track`): the route is followed segment by segment; the target is the
  point ``lookahead`` metres ahead of the torso's projection on the current segment, never past
  the segment's end, so the robot does not cut the corner at a waypoint (the corners are the
  obstacles' corners grown by the clearance). A segment is done when the projection is within
  ``capture`` of its end.
* **Gait choice** (:func:`choose`): the robot walks with the forward gait, steering with its
  ``turn_rate`` = heading error x ``steer_gain`` (clamped to ``max_steer``) and shortening its
  step length from full at ``slow_deg`` of heading error to ``min_step`` of it at
  ``stop_deg``, so it takes a corner on an arc that tightens with the error, with no switch
  of gait. Above ``turn_deg`` (by default 180: never) it would turn on the spot with the
  library's left or right turning gait until the error is below ``resume_deg`` or has
  changed sign (an overshoot hands over to the forward gait, never to the opposite turn).
* **Library cells** (a gait library with ``forward_cells``, e.g. ``nao_library`` drawn from
  the MAP-Elites archive): the forward gait is itself chosen each step cycle among the cells,
  the fastest whose measured speed is at most the step fraction times the fastest cell's
  (:func:`pick_cell`), instead of one gait's step being shortened, and steered as the forward
  gait is. (Steering a cell by the heading error less its measured travel direction, which
  is up to 30 degrees off its torso's heading for some cells, made the robot fall in its first
  seconds on the tuning scenes: claim ``walk-library-travel-steer-falls``.)
* **Start ramp** (``start_ramp_s``, 0 by default; a gait library's file may name its own): over
  the walk's first seconds the forward step fraction is capped at the elapsed share of them
  (:func:`start_cap`), so the walk starts slow, with library cells on the slowest.
* **Gait changes**: a new choice is made at the start of each step cycle; the walk engine's
  parameters then blend linearly from the old ones to the new over ``blend_cycles`` cycles
  while the gait phase runs on continuously (the engine is evaluated at the phase, not at the
  clock), so a switch never jumps the feet. The first ``RAMP_TIME`` seconds are the engine's
  start-up ramp of the first gait.

A walk succeeds when the torso comes within ``goal_radius`` (0.15 m) of the goal with no fall
(the spec's fall rule, the torso height taken above the ground under it, ramps included) and no
contact between any robot geom and any obstacle geom before then. Randomised worlds
(:mod:`eaco_jax.gait.worlds`: friction, masses, motors, target noise, latency, initial pose,
one push during the planned walking time) enter exactly as in the gait rollouts.

**Motors** (``motors``): ``"servo"`` (the default) simulates the scene model's position servos
with the MJCF's force clamp, each control step's target held for its physics steps.
``"spec"`` simulates the robot spec's motor model as the gait rollouts do
(:func:`motor_physics`): with ``motors.limits_in_physics`` the actuators are direct-torque
ones (:func:`~eaco_jax.gait.rollout_native.to_torque_actuators`) and each physics step's
torque is :func:`~eaco_jax.gait.quality.motor_torque` of that step's joint state (current
limit, back-EMF, gear efficiency); with ``motors.interpolate_targets`` the target moves
linearly to the next control step's over the physics steps
(:func:`~eaco_jax.gait.motors.physics_targets`). The next control step's target is known
before its step cycle's decision: a new cycle's first control step runs the blend where it
stood (its new parameters enter from the second step on), so the controller decides as with
held targets.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math
from importlib import resources
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.gait import motors as mo
from eaco_jax.gait import quality as ql
from eaco_jax.gait import scene_world as sw
from eaco_jax.gait.robot import RobotSpec
from eaco_jax.gait.rollout_native import nominal_motor, to_torque_actuators
from eaco_jax.gait.walk_engine import PARAM_NAMES, RAMP_TIME, gait_vector, joint_targets
from eaco_jax.gait.worlds import (
    VARIED_FIELDS,
    RobustConfig,
    Worlds,
    actuated_dofs,
    couple_controls,
    initial_qpos,
    native_world_models,
    sample_worlds,
    stream_key,
)

FORWARD, LEFT, RIGHT = "forward", "turn_left", "turn_right"
MODES = (FORWARD, LEFT, RIGHT)
TURN = PARAM_NAMES.index("turn_rate")
PERIOD = PARAM_NAMES.index("period")
STEP = PARAM_NAMES.index("step_length")
MAX_CYCLE_STEPS = 64
"""Control steps of the longest step cycle a chunk holds (the engine's period bound / dt)."""
MOTORS = ("servo", "spec")
"""Walk motor models: the scene model's position servos, or the robot spec's motor model."""


def motor_physics(spec: RobotSpec, motors: str) -> tuple[bool, bool]:
    """``(limits in the physics, interpolated targets)`` of a walk's ``motors`` setting:
    none for ``"servo"``, the spec's (:func:`~eaco_jax.gait.motors.physics_limits`,
    :func:`~eaco_jax.gait.motors.interpolates_targets`, as the gait rollouts apply them) for
    ``"spec"``."""
    if motors not in MOTORS:
        raise ConfigError(f"motors must be one of {', '.join(MOTORS)}, got {motors!r}")
    if motors == "servo":
        return False, False
    return mo.physics_limits(spec), mo.interpolates_targets(spec)


# --------------------------------------------------------------------------- gait library
@dataclasses.dataclass(frozen=True)
class WalkGaits:
    """The controller's gait library: walk-engine parameter vectors (``PARAM_NAMES`` order)."""

    forward: np.ndarray
    turn_left: np.ndarray
    turn_right: np.ndarray
    source: str = ""
    planning: dict[str, Any] | None = None  # speed_mps, yaw_rate_deg_s a planner should price
    #: forward cells ``(K, P)``, slowest first, the controller picks among (None: one forward
    #: gait whose step it shortens), and their measured forward speeds [m/s] ``(K,)``
    cells: np.ndarray | None = dataclasses.field(default=None, compare=False)
    cell_speed: np.ndarray | None = dataclasses.field(default=None, compare=False)
    #: controller settings chosen for this library (its file's ``controller`` entry, fields
    #: of :data:`LIBRARY_CONTROLLER`), used where the walk does not set them
    controller: tuple[tuple[str, float], ...] = ()

    @property
    def start_ramp_s(self) -> float:
        """The library's start ramp (0 where it names none)."""
        return dict(self.controller).get("start_ramp_s", 0.0)

    def of(self, mode: str) -> np.ndarray:
        return np.asarray(getattr(self, mode), np.float64)

    @property
    def n_cells(self) -> int:
        return 0 if self.cells is None else len(self.cells)


def pick_cell(gaits: WalkGaits, step: float) -> int:
    """The forward cell for a step fraction ``step`` (in (0, 1]): the fastest whose measured
    speed is at most ``step`` times the fastest cell's, the slowest if none is."""
    s = gaits.cell_speed
    return max(0, int(np.sum(s <= step * s[-1] + 1e-6)) - 1)


def _forward_cells(data: dict, path: Path) -> tuple[np.ndarray, ...] | tuple[None, ...]:
    """``(cells, speed)`` of a library file's ``forward_cells`` (sorted by speed), or Nones
    where it has none."""
    entries = data.get("forward_cells")
    if entries is None:
        return None, None
    try:
        vecs = [np.asarray(e["vector"], np.float64) for e in entries]
        speed = np.array([float(e["speed_mps"]) for e in entries])
    except (KeyError, TypeError, ValueError) as err:
        raise ConfigError(f"{path}: each of forward_cells needs vector and speed_mps "
                          f"({type(err).__name__}: {err})") from None
    if not vecs or not (np.all(np.isfinite(speed)) and np.all(speed > 0)):
        raise ConfigError(f"{path}: forward_cells needs at least one cell, each with "
                          f"speed_mps > 0")
    for i, v in enumerate(vecs):
        try:
            gait_vector(v, len(PARAM_NAMES), f"{path}: forward_cells[{i}].vector")
        except ProblemError as err:
            raise ConfigError(f"{err} ({', '.join(PARAM_NAMES)})") from None
    order = np.argsort(speed, kind="stable")
    return np.stack(vecs)[order], speed[order]


def load_walk_gaits(name_or_path: str | Path = "nao") -> WalkGaits:
    """A gait library: a shipped name (``eaco_jax/data/walk_gaits/<name>.json``) or a JSON file
    with ``gaits.forward|turn_left|turn_right.vector``."""
    path = Path(name_or_path)
    if path.suffix != ".json":
        path = Path(str(resources.files("eaco_jax") / "data" / "walk_gaits" / f"{path}.json"))
    try:
        data = json.loads(path.read_text())
        vecs = {m: np.asarray(data["gaits"][m]["vector"], np.float64) for m in MODES}
    except OSError as err:
        raise ConfigError(f"cannot read gait library {path}: {err.strerror or err}") from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as err:
        raise ConfigError(f"{path}: a gait library needs gaits.forward, gaits.turn_left and "
                          f"gaits.turn_right with a 'vector' each ({type(err).__name__}: "
                          f"{err})") from None
    for m, v in vecs.items():
        try:
            gait_vector(v, len(PARAM_NAMES), f"{path}: gaits.{m}.vector")
        except ProblemError as err:  # a file's fault: a ConfigError naming the parameters
            raise ConfigError(f"{err} ({', '.join(PARAM_NAMES)})") from None
    planning = data.get("planning")
    if planning is not None:
        try:
            ok = all(float(planning[k]) > 0 for k in ("speed_mps", "yaw_rate_deg_s"))
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise ConfigError(f"{path}: planning needs speed_mps and yaw_rate_deg_s > 0")
    cells, speed = _forward_cells(data, path)
    return WalkGaits(vecs[FORWARD], vecs[LEFT], vecs[RIGHT], str(data.get("source", "")),
                     planning, cells, speed, _library_controller(data.get("controller"), path))


#: the controller settings a gait library's file may choose for itself (``controller``)
LIBRARY_CONTROLLER = ("start_ramp_s", "turn_deg", "resume_deg", "steer_gain", "max_steer",
                      "slow_deg", "stop_deg", "min_step", "goal_turn_deg")


def _library_controller(entry: Any, path: Path) -> tuple[tuple[str, float], ...]:
    """A library file's ``controller`` entry as ``(field, value)`` pairs: numbers for fields
    of :data:`LIBRARY_CONTROLLER`, plus informational ``claim`` / ``claims``; checked by
    building a :class:`Controller` of them."""
    entry = entry or {}
    fields = set(entry) - {"claim", "claims"} if isinstance(entry, dict) else None
    if (fields is None or fields - set(LIBRARY_CONTROLLER)
            or not all(isinstance(entry[f], (int, float)) and not isinstance(entry[f], bool)
                       for f in fields)):
        raise ConfigError(f"{path}: controller may only set {', '.join(LIBRARY_CONTROLLER)} "
                          f"(numbers), got {entry!r}")
    pairs = tuple(sorted((f, float(entry[f])) for f in fields))
    try:
        Controller(**dict(pairs))
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}") from None
    return pairs


# --------------------------------------------------------------------------- controller
@dataclasses.dataclass(frozen=True)
class Controller:
    """Settings of the path-following controller (lengths in m, angles in deg, rates in rad/s).

    The defaults were chosen on tuning scenes and selection-stream worlds (claims
    ``walk-controller-selection``; ``walk-steer-tuning-chosen`` for ``steer_gain``;
    ``walk-spec-stop-deg-120-successes`` for ``stop_deg`` on the motor model;
    ``walk-spec-goal-turn-60-successes`` for ``goal_turn_deg``), not on the
    scenes and worlds the walk is reported on.
    """

    lookahead: float = 0.9
    capture: float = 0.3
    turn_deg: float = 180.0  # turn on the spot above this heading error (180: never)
    resume_deg: float = 20.0  # ... until the error is below this
    steer_gain: float = 1.2  # forward gait's turn_rate [rad/s] per rad of heading error
    max_steer: float = 0.8  # clamp of the forward gait's turn_rate [rad/s]
    slow_deg: float = 15.0  # the forward gait's step shortens above this heading error ...
    stop_deg: float = 120.0  # ... to min_step of its length at this error and beyond
    min_step: float = 0.35
    goal_turn_deg: float = 60.0  # within lookahead of the goal: turn_deg (180: never)
    #: within this distance [m] of a bend the forward step is capped as if the heading error
    #: were the bend's turn times the fraction of the distance already covered (0: off, the
    #: default: on the tuning scenes it brought walks nearer obstacles, claim
    #: walk-spec-bend-1p0-closest-approach)
    bend_distance: float = 0.0
    #: over the first this many seconds the forward step fraction is capped at the elapsed
    #: share of them (at least ``min_step``): the walk starts slow and speeds up; with
    #: library cells it climbs through them, slowest first (0: off)
    start_ramp_s: float = 0.0
    blend_cycles: float = 0.5
    goal_radius: float = 0.15

    def __post_init__(self) -> None:
        for name in ("lookahead", "capture", "turn_deg", "steer_gain", "max_steer",
                     "blend_cycles", "goal_radius"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"controller {name} must be a finite number > 0, got {v!r}")
        if self.turn_deg > 180:
            raise ConfigError(f"controller turn_deg must be <= 180 (180: never turn on the "
                              f"spot), got {self.turn_deg}")
        if not 0 <= self.resume_deg < self.turn_deg:
            raise ConfigError(f"controller resume_deg must be in [0, turn_deg={self.turn_deg}),"
                              f" got {self.resume_deg}")
        if not (math.isfinite(self.goal_turn_deg) and self.resume_deg < self.goal_turn_deg
                <= 180):
            raise ConfigError(f"controller goal_turn_deg must be in (resume_deg="
                              f"{self.resume_deg}, 180] (180: never), got {self.goal_turn_deg!r}")
        if not 0 <= self.slow_deg < self.stop_deg:
            raise ConfigError(f"controller slow_deg must be in [0, stop_deg={self.stop_deg}), "
                              f"got {self.slow_deg}")
        if not 0 < self.min_step <= 1:
            raise ConfigError(f"controller min_step must be in (0, 1], got {self.min_step}")
        if not (math.isfinite(self.start_ramp_s) and self.start_ramp_s >= 0):
            raise ConfigError(f"controller start_ramp_s must be a finite number >= 0 (0: off),"
                              f" got {self.start_ramp_s!r}")
        if not (math.isfinite(self.bend_distance) and self.bend_distance >= 0):
            raise ConfigError(f"controller bend_distance must be a finite number >= 0 (0: off),"
                              f" got {self.bend_distance!r}")


@dataclasses.dataclass(frozen=True)
class Choice:
    """One step cycle's gait: the mode, the forward gait's ``turn_rate`` [rad/s] and the
    fraction of its step length (both unused while turning on the spot); ``cell``: the
    library's forward cell walked instead of the shortened forward gait (-1: none)."""

    mode: str
    steer: float = 0.0
    step: float = 1.0
    cell: int = -1


def wrap(angle: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def track(route: np.ndarray, seg: int, pos: np.ndarray, ctrl: Controller) -> tuple[int, np.ndarray]:
    """The current segment index (advanced past segments whose end the torso's projection
    has reached within ``capture``) and the target point on it, ``lookahead`` ahead of the
    projection and never beyond the segment's end."""
    last = len(route) - 2
    while True:
        a, b = route[seg], route[seg + 1]
        d = b - a
        length = float(np.linalg.norm(d))
        unit = d / max(length, 1e-12)
        along = float((pos - a) @ unit)
        if seg < last and (along >= length - ctrl.capture
                           or np.linalg.norm(pos - b) <= ctrl.capture):
            seg += 1
            continue
        return seg, a + unit * min(length, max(along, 0.0) + ctrl.lookahead)


def choose(error: float, mode: str, ctrl: Controller) -> Choice:
    """The gait for the next step cycle from the heading error [rad] (+: target to the left)
    and the current mode.

    Above ``turn_deg`` the robot turns on the spot, until the error is below ``resume_deg`` or
    has changed sign (an overshoot hands over to the forward gait, never to the opposite
    turn). Otherwise it walks with the forward gait, steering with ``turn_rate`` = error x
    ``steer_gain`` clamped to ``max_steer``, its step length shortened linearly from full at
    ``slow_deg`` to ``min_step`` at ``stop_deg``: it takes a corner on an arc that tightens
    with the error, without switching gaits."""
    big = math.radians(ctrl.turn_deg)
    small = math.radians(ctrl.resume_deg)
    turning = mode in (LEFT, RIGHT)
    overshot = (mode == LEFT and error < 0) or (mode == RIGHT and error > 0)
    if turning and not overshot and abs(error) > small:
        return Choice(mode)
    if abs(error) > big and not overshot:
        return Choice(LEFT if error > 0 else RIGHT)
    steer = max(-ctrl.max_steer, min(ctrl.max_steer, ctrl.steer_gain * error))
    return Choice(FORWARD, steer, step_fraction(abs(error), ctrl))


def step_fraction(error: float, ctrl: Controller) -> float:
    """The forward step's fraction for a heading error of ``error`` rad (>= 0): full up to
    ``slow_deg``, down linearly to ``min_step`` at ``stop_deg``."""
    u = (math.degrees(error) - ctrl.slow_deg) / (ctrl.stop_deg - ctrl.slow_deg)
    return 1.0 - (1.0 - ctrl.min_step) * min(1.0, max(0.0, u))


def bend_cap(route: np.ndarray, seg: int, pos: np.ndarray, ctrl: Controller) -> float:
    """The forward step's cap ahead of the bend at the end of segment ``seg``: the step for a
    heading error of the bend's turn times ``1 - distance / bend_distance`` (the torso's
    distance to the bend), so the robot slows before a corner instead of after it; 1 with
    ``bend_distance`` 0, on the last segment and farther than ``bend_distance``."""
    if ctrl.bend_distance <= 0 or seg >= len(route) - 2:
        return 1.0
    a, b, c = route[seg], route[seg + 1], route[seg + 2]
    turn = abs(wrap(math.atan2(c[1] - b[1], c[0] - b[0]) - math.atan2(b[1] - a[1], b[0] - a[0])))
    near = min(1.0, max(0.0, 1.0 - float(np.linalg.norm(b - pos)) / ctrl.bend_distance))
    return step_fraction(turn * near, ctrl)


def near_goal(ctrl: Controller) -> Controller:
    """The controller within ``lookahead`` of the goal on the last segment: it turns on the
    spot above ``goal_turn_deg`` (a robot whose steered arc is wider than ``goal_radius``
    would otherwise circle the goal)."""
    return dataclasses.replace(ctrl, turn_deg=min(ctrl.turn_deg, ctrl.goal_turn_deg))


def start_cap(t: float, ctrl: Controller) -> float:
    """The forward step's cap at walking time ``t`` [s]: the elapsed share of
    ``start_ramp_s``, at least ``min_step`` (1 once it has passed, or with it 0)."""
    if ctrl.start_ramp_s <= 0:
        return 1.0
    return min(1.0, max(ctrl.min_step, t / ctrl.start_ramp_s))


def with_cell(choice: Choice, gaits: WalkGaits) -> Choice:
    """A forward choice on a library with cells: the cell for its step fraction
    (:func:`pick_cell`), its steering unchanged."""
    if choice.mode != FORWARD or gaits.cells is None:
        return choice
    return dataclasses.replace(choice, cell=pick_cell(gaits, choice.step))


def gait_params(gaits: WalkGaits, choice: Choice) -> np.ndarray:
    """The walk-engine parameters of a choice: a library gait, the forward one steered and
    its step length scaled."""
    if choice.mode == FORWARD and choice.cell >= 0:
        params = np.asarray(gaits.cells[choice.cell], np.float64).copy()
        params[TURN] = choice.steer
        return params
    params = gaits.of(choice.mode).copy()
    if choice.mode == FORWARD:
        params[TURN] = choice.steer
        params[STEP] *= choice.step
    return params


# --------------------------------------------------------------------------- engine
@functools.lru_cache(maxsize=8)
def _targets_fn(spec: RobotSpec):
    """Jitted targets ``(L, nu)`` of per-step parameters ``(L, P)`` at engine times ``(L,)``."""
    return jax.jit(jax.vmap(lambda p, t: joint_targets(p, t, spec)))


def _phase_time(k: int, dt: float, phase: float, period: float) -> float:
    """The engine time that puts a gait of ``period`` at ``phase`` (cycles) with its start-up
    ramp done; the clock itself during the first RAMP_TIME seconds."""
    t = k * dt
    if t < RAMP_TIME:
        return t
    m = math.ceil(RAMP_TIME / period) + 1
    return (m + (phase % 1.0)) * period


# --------------------------------------------------------------------------- worlds
@dataclasses.dataclass
class WorldInputs:
    """What one randomised world changes in a walk (nominal: the defaults)."""

    model: mujoco.MjModel | None = None  # None: the scene's nominal model
    latency: int = 0
    noise: np.ndarray | None = None  # (T, nu) target noise per control step
    push_start: int = -1
    push_stop: int = -1
    push_force: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    qpos: np.ndarray | None = None  # initial configuration (None: the keyframe)
    motor: ql.MotorParams | None = None  # the world's motor parameters (None: the model's)


def walk_worlds(model: mujoco.MjModel, spec: RobotSpec, n: int, push_steps: int, seed: int,
                stream: str, cfg: RobustConfig | None) -> Worlds:
    """The ``n`` worlds both route walkers draw (batch 0 of ``stream`` of ``seed``, ``cfg``'s
    ranges, default :class:`RobustConfig`); joint play is refused: no walker models it yet."""
    cfg = cfg or RobustConfig()
    if cfg.joint_play:
        raise ProblemError(f"joint_play {cfg.joint_play} is not modelled by the route walker yet; "
                           "walk with joint_play=0 (RobustConfig's default)")
    return sample_worlds(stream_key(seed, stream), cfg, spec, model.nbody, push_steps, r=n)


def sample_walk_worlds(model: mujoco.MjModel, spec: RobotSpec, n: int, n_steps: int,
                       push_steps: int, seed: int = 0, stream: str = "test",
                       cfg: RobustConfig | None = None) -> tuple[list[WorldInputs], Worlds]:
    """``n`` randomised worlds (:func:`~eaco_jax.gait.worlds.sample_worlds` on batch 0 of
    ``stream`` of ``seed``) as walk inputs: per-world models (the ramps and obstacles take the
    world's floor friction), ``n_steps`` control steps of target noise, a push within the
    first ``push_steps`` control steps, the initial pose offsets."""
    worlds = walk_worlds(model, spec, n, push_steps, seed, stream, cfg)
    wn = jax.tree.map(np.asarray, worlds)
    models = native_world_models(model, spec, wn)
    extra = sw.geom_ids(model, "ramp") + sw.geom_ids(model, "obstacle")
    for i, m in enumerate(models):
        m.geom_friction[extra, 0] = float(wn.friction[i])
    keys = jax.vmap(lambda t: jax.random.fold_in(worlds.noise_key, t))(jnp.arange(n_steps))
    noise = jax.vmap(lambda k: jax.random.normal(k, (n, spec.nu), jnp.float32))(keys)
    noise = np.asarray(noise * worlds.noise_std)  # (T, n, nu)
    qadr = np.array([model.joint(j).qposadr[0] for j in spec.joint_names])
    lo, hi = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
    stand = sw.start_qpos(spec, model, (0.0, 0.0), 0.0)  # the walk sets the start and heading
    qinit = initial_qpos(stand, wn, qadr, lo, hi, xp=np)
    dofs = actuated_dofs(model, spec)
    motor = [ql.motor_params({k: getattr(m, k) for k in VARIED_FIELDS}, spec, dofs,
                             model.actuator_ctrlrange, wn.stall_scale[i], wn.speed_scale[i],
                             xp=np) if spec.has_motors else None
             for i, m in enumerate(models)]
    out = [WorldInputs(model=models[i], latency=int(wn.latency[i]), noise=noise[:, i],
                       push_start=int(wn.push_start[i]), push_stop=int(wn.push_stop[i]),
                       push_force=np.asarray(wn.push_force[i], np.float64),
                       qpos=np.asarray(qinit[i], np.float64), motor=motor[i])
           for i in range(n)]
    return out, worlds


# --------------------------------------------------------------------------- geometry helpers
def _ramp_planes(scene: Any) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    out = []
    for r in scene.ramps:
        poly = np.asarray(r.polygon, np.float64)
        u = np.array([math.cos(math.radians(r.uphill_deg)), math.sin(math.radians(r.uphill_deg))])
        if r.slope_deg < 0:
            u = -u
        out.append((poly, u, math.tan(math.radians(abs(r.slope_deg))), float((poly @ u).min())))
    return out


def _inside(p: np.ndarray, poly: np.ndarray) -> bool:
    e = np.roll(poly, -1, axis=0) - poly
    w = p - poly
    return bool(np.all(e[:, 0] * w[:, 1] - e[:, 1] * w[:, 0] >= 0))


def ground_height(planes: list, xy: np.ndarray) -> float:
    """Height [m] of the ground (floor or ramp top) under the point ``xy``."""
    for poly, u, tan, low in planes:
        if _inside(xy, poly):
            return tan * (float(xy @ u) - low)
    return 0.0


def polygon_distance(p: np.ndarray, poly: np.ndarray) -> float:
    """Euclidean distance from ``p`` to a convex counter-clockwise polygon (0 inside)."""
    if _inside(p, poly):
        return 0.0
    a, b = poly, np.roll(poly, -1, axis=0)
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + t[:, None] * d - p, axis=1)))


# --------------------------------------------------------------------------- the walk
def start_heading(scene: Any, route: np.ndarray) -> float:
    """The scene's start heading [rad] if it gives one, else the first segment's heading
    (the planner's free start)."""
    if scene.start_heading_deg is not None:
        return math.radians(scene.start_heading_deg)
    d = route[1] - route[0]
    return math.atan2(d[1], d[0])


def walk(scene: Any, route: np.ndarray, spec: RobotSpec, gaits: WalkGaits,
         ctrl: Controller | None = None, *, max_time: float = 60.0,
         model: mujoco.MjModel | None = None, world: WorldInputs | None = None,
         record_every: int = 5, distmax: float = 1.0,
         decisions: list | None = None, motors: str = "servo") -> dict[str, Any]:
    """Walk ``route`` (``(k, 2)`` waypoints, start first) through ``scene`` for at most
    ``max_time`` seconds; the walk's record (trajectory, success, times, closest approach).

    ``model``: the scene's model (:func:`~eaco_jax.gait.scene_world.scene_model` with the robot
    facing :func:`start_heading`), built if not given; ``world`` one randomised world's inputs.
    The trajectory keeps every ``record_every``-th control step; ``decisions``, if a list,
    receives ``(t, segment, heading error, mode, steer, step)`` at every step cycle.
    ``motors``: ``"servo"`` or ``"spec"`` (the robot spec's motor model, see the module).
    """
    ctrl = ctrl or Controller()
    route = np.asarray(route, np.float64)
    if route.ndim != 2 or route.shape[1] != 2 or len(route) < 2:
        raise ProblemError(f"route must be (k >= 2, 2) waypoints, got shape {route.shape}")
    if not (math.isfinite(max_time) and max_time > 0):
        raise ConfigError(f"max_time must be a finite number > 0, got {max_time!r}")
    heading0 = start_heading(scene, route)
    if model is None:
        model = sw.scene_model(scene, spec, start_heading=heading0)
    limits, interpolate = motor_physics(spec, motors)
    world = world or WorldInputs()
    m = world.model or model
    mm = mo.motor_model(spec)  # None: no electrical data, no currents
    mp = None
    dofs = np.asarray(actuated_dofs(m, spec))
    qadr = np.array([m.joint(j).qposadr[0] for j in spec.joint_names])
    if mm is not None:
        mp = world.motor if world.motor is not None else nominal_motor(spec, m)
        mp = ql.MotorParams(*(np.asarray(x, np.float64) for x in mp))
    if limits:
        m = to_torque_actuators(copy.copy(m), dofs, mo.friction_share(spec))
    data = mujoco.MjData(m)
    data.qpos[:] = (world.qpos if world.qpos is not None
                    else sw.start_qpos(spec, m, tuple(route[0]), heading0))
    data.qpos[:2] = route[0]
    data.qpos[3:7] = [math.cos(heading0 / 2), 0.0, 0.0, math.sin(heading0 / 2)]
    data.ctrl[:] = spec.stand_ctrl
    mujoco.mj_forward(m, data)
    dt = spec.control_dt
    sub = int(round(dt / m.opt.timestep))
    n_steps = int(math.ceil(max_time / dt))
    targets_fn = _targets_fn(spec)
    obstacles = sw.geom_ids(m, "obstacle")
    robot = sw.robot_geom_ids(m)
    polys = [np.asarray(o.polygon, np.float64) for o in scene.obstacles]
    planes = _ramp_planes(scene)
    goal = np.asarray(route[-1], np.float64)
    cos_tilt = math.cos(math.radians(spec.fall_tilt_deg))

    mode, seg = FORWARD, 0
    last = Choice(FORWARD)
    p_old = p_new = None
    phase, alpha = 0.0, 1.0
    chunk: np.ndarray | None = None
    chunk_next: np.ndarray | None = None  # the target after the chunk's last
    chunk_pos = 0
    history: list[np.ndarray] = []
    rows: list[list[float]] = []
    modes_time = {m_: 0.0 for m_ in MODES}
    cells_time = np.zeros(gaits.n_cells)
    closest, closest_obstacle = distmax, -1
    contact_time, contact_obstacle = None, -1
    fell_time = reach_time = None
    switches = 0
    peak_current = 0.0
    k = 0
    yaws: list[float] = [heading0]
    for k in range(n_steps):
        pos = data.qpos[:2].copy()
        if chunk is None or chunk_pos >= len(chunk):
            yaw = _mean_angle(yaws[-max(1, len(chunk) if chunk is not None else 1):])
            seg, target = track(route, seg, pos, ctrl)
            near = np.linalg.norm(goal - pos) < ctrl.lookahead and seg == len(route) - 2
            if near:
                target = goal
            error = wrap(math.atan2(target[1] - pos[1], target[0] - pos[0]) - yaw)
            choice = choose(error, mode, near_goal(ctrl) if near else ctrl)
            if choice.mode == FORWARD and ctrl.bend_distance > 0:
                choice = dataclasses.replace(
                    choice, step=min(choice.step, bend_cap(route, seg, pos, ctrl)))
            if choice.mode == FORWARD and ctrl.start_ramp_s > 0:
                choice = dataclasses.replace(choice, step=min(choice.step,
                                                              start_cap(k * dt, ctrl)))
            choice = with_cell(choice, gaits)
            if k * dt < RAMP_TIME and p_new is not None:
                choice = last  # no switch during the start-up
            last = choice
            new_mode = choice.mode
            params = gait_params(gaits, choice)
            if p_new is None:
                p_old = p_new = params
            else:
                p_old = (1 - alpha) * p_old + alpha * p_new
                p_new = params
                alpha = 0.0
            if decisions is not None:
                decisions.append((round(k * dt, 3), seg, error, new_mode, choice.steer,
                                  choice.step))
            switches += int(new_mode != mode)
            mode = new_mode
            chunk, phase, alpha = _cycle(p_old, p_new, alpha, phase, k, dt,
                                         ctrl.blend_cycles, targets_fn, extra=interpolate)
            if interpolate:
                chunk, chunk_next = chunk[:-1], chunk[-1]
            chunk_pos = 0
        cmd = chunk[chunk_pos]
        chunk_pos += 1
        history.append(cmd)
        u = _world_target(history, k, world, spec)
        data.qfrc_applied[:3] = (world.push_force if world.push_start <= k < world.push_stop
                                 else 0.0)
        u_next = u
        if interpolate:
            nxt = chunk[chunk_pos] if chunk_pos < len(chunk) else chunk_next
            u_next = _world_target(history + [nxt], k + 1, world, spec)
        targets = mo.physics_targets(u, u_next, sub, interpolate, np)  # (sub, nu)
        q0, v0, v1, force = (np.empty((sub, spec.nu)) for _ in range(4))
        for j in range(sub):
            q0[j], v0[j] = data.qpos[qadr], data.qvel[dofs]
            data.ctrl[:] = (ql.motor_torque(q0[j], v0[j], targets[j], mp, mm, np) if limits
                            else targets[j])
            mujoco.mj_step(m, data)
            v1[j], force[j] = data.qvel[dofs], data.actuator_force
        if mm is not None:  # the currents as the gait rollouts' quality accumulators take them
            tau, qd = ((force, v0) if limits else
                       (ql.drive_torque(q0, v1, targets, mp, np), v1))
            peak_current = max(peak_current, float(np.max(
                np.abs(mo.current(tau, qd, mm, np)) / mm.i_limit)))
        modes_time[mode] += dt
        if last.cell >= 0 and mode == FORWARD:
            cells_time[last.cell] += dt
        t = (k + 1) * dt
        pos = data.qpos[:2]
        yaws.append(_yaw(data.qpos[3:7]))
        # contacts and the closest approach (obstacles whose bounding circle is near)
        near = np.array([polygon_distance(pos, p) < distmax + 0.4 for p in polys], bool)
        if near.any():
            dist = sw.obstacle_distances(m, data, robot, obstacles, near, distmax)
            j = int(np.argmin(dist))
            if dist[j] < closest:
                closest, closest_obstacle = float(dist[j]), j
            if dist[j] <= 0.0 and contact_time is None:
                contact_time, contact_obstacle = t, j
        z = float(data.qpos[2]) - ground_height(planes, pos)
        up_z = 1.0 - 2.0 * float(data.qpos[4] ** 2 + data.qpos[5] ** 2)
        if (k + 1) % record_every == 0:
            rows.append([round(t, 3), float(pos[0]), float(pos[1]), _yaw(data.qpos[3:7]),
                         MODES.index(mode)])
        if z < spec.fall_height or up_z < cos_tilt:
            fell_time = t
            break
        if np.linalg.norm(goal - pos) <= ctrl.goal_radius:
            reach_time = t
            break
    t_end = (k + 1) * dt
    if not rows or rows[-1][0] != round(t_end, 3):
        rows.append([round(t_end, 3), float(data.qpos[0]), float(data.qpos[1]),
                     _yaw(data.qpos[3:7]), MODES.index(mode)])
    reached = reach_time is not None
    return {
        "motors": motors,
        "success": bool(reached and contact_time is None and fell_time is None),
        "reached": reached,
        "reach_time_s": reach_time,
        "fell": fell_time is not None,
        "fall_time_s": fell_time,
        "contact": contact_time is not None,
        "contact_time_s": contact_time,
        "contact_obstacle": contact_obstacle if contact_time is not None else None,
        "closest_approach_m": closest,
        "closest_obstacle": closest_obstacle if closest < distmax else None,
        "goal_distance_m": float(np.linalg.norm(goal - data.qpos[:2])),
        "walked_time_s": t_end,
        "walked_length_m": _length(np.asarray([r[1:3] for r in rows])),
        "mode_seconds": {k_: round(v, 3) for k_, v in modes_time.items()},
        "gait_switches": switches,
        "cell_seconds": [round(float(v), 3) for v in cells_time] if gaits.n_cells else None,
        "peak_current_frac": peak_current if mm is not None else None,
        "trajectory_columns": ["t", "x", "y", "yaw", "mode"],
        "trajectory": rows,
    }


def _world_target(history: list[np.ndarray], k: int, world: WorldInputs,
                  spec: RobotSpec) -> np.ndarray:
    """The target control step ``k`` sends to the motors: the engine's command ``latency``
    steps back in ``history`` (whose last entry is step ``k``'s), plus the world's target
    noise, the coupled joints coupled."""
    u = history[max(0, len(history) - 1 - world.latency)]
    if world.noise is not None:
        u = u + world.noise[min(k, len(world.noise) - 1)]
    return couple_controls(np.asarray(u)[None], spec, xp=np)[0]


def _cycle(p_old: np.ndarray, p_new: np.ndarray, alpha: float, phase: float, k0: int,
           dt: float, blend_cycles: float, targets_fn,
           extra: bool = False) -> tuple[np.ndarray, float, float]:
    """Targets ``(L, nu)`` of one step cycle from control step ``k0`` (until the phase passes
    its next whole cycle), the parameters blending from ``p_old`` to ``p_new``; the phase and
    the blend after it. ``extra``: one more row, the next cycle's first target (that step
    runs the blend where it stands, whatever the next decision)."""
    params, times = [], []
    end = math.floor(phase + 1e-9) + 1
    k = k0
    while len(params) < MAX_CYCLE_STEPS:
        p = (1 - alpha) * p_old + alpha * p_new
        params.append(p)
        times.append(_phase_time(k, dt, phase, float(p[PERIOD])))
        phase += dt / float(p[PERIOD])
        alpha = min(1.0, alpha + dt / (blend_cycles * float(p_new[PERIOD])))
        k += 1
        if phase >= end - 1e-9:
            break
    n = len(params)
    if extra:
        p = (1 - alpha) * p_old + alpha * p_new
        params.append(p)
        times.append(_phase_time(k, dt, phase, float(p[PERIOD])))
        n += 1
    pad = MAX_CYCLE_STEPS + int(extra) - n
    P = np.concatenate([np.asarray(params), np.repeat(np.asarray(params)[-1:], pad, 0)])
    T = np.concatenate([np.asarray(times), np.full(pad, times[-1])])
    out = np.asarray(targets_fn(jnp.asarray(P, jnp.float32), jnp.asarray(T, jnp.float32)))
    return out[:n].astype(np.float64), phase, alpha


def _mean_angle(angles: list[float]) -> float:
    """Circular mean [rad] (the torso's yaw over a step cycle, without its sway)."""
    a = np.asarray(angles)
    return math.atan2(float(np.sin(a).mean()), float(np.cos(a).mean()))


def _yaw(q: np.ndarray) -> float:
    w, x, y, z = (float(v) for v in q)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _length(xy: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))) if len(xy) > 1 else 0.0


__all__ = ["FORWARD", "LEFT", "MODES", "MOTORS", "RIGHT", "Choice", "Controller", "WalkGaits",
           "WorldInputs", "choose", "gait_params", "ground_height", "load_walk_gaits",
           "motor_physics", "pick_cell", "polygon_distance", "sample_walk_worlds",
           "start_cap", "start_heading", "track", "walk", "with_cell", "wrap"]
