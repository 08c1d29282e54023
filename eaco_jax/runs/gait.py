"""The ``gait`` and ``gait-eval`` runs: optimise a walking gait, or re-simulate a stored one.

``gait`` lets the continuous EACO colony search the walk engine's parameters
(:mod:`eaco_jax.gait.walk_engine`): every iteration rolls the whole colony out as one batched
simulation (``backend="native"``: MuJoCo's C engine on all CPU threads, the CPU default;
``"mjx"``: MJX, the GPU default) and scores each gait by the paper's fitness (distance walked in
the desired direction within ``horizon`` seconds; falls, no progress and drift > 45 degrees
score 0). The best gait is then re-simulated and written to ``out``:

* ``best_gait.json``: parameters by name and as a vector, robot, horizon, direction, slope,
  backend, seed, iterations and the measured metrics (speed, distance, fall, drift, fitness);
* ``history.csv`` and ``convergence.png``: best-so-far and colony-mean fitness per iteration;
* ``joint_angles.png``: hip, knee and ankle angles of both legs against time (paper Figs. 3, 10);
* ``best_gait.mp4``: an offscreen video of the best gait (skipped, with a message on stderr, when
  no OpenGL context can be made; ``video=False`` skips it on purpose).

``init`` warm-starts from a stored gait (``best_gait.json``): the colony then searches a box of
+/- 15% of each parameter's range around it instead of the full range.

``constrained`` maximises speed under the motor, slip, drift and fall constraints of
:mod:`eaco_jax.gait.constraints` with the colony's own constraint handling
(``constraint_method``); the record holds each constraint's value, limit and margin.

Randomised worlds come from three key streams of the run's seed
(:data:`eaco_jax.gait.worlds.STREAMS`): the search sees the optimisation stream, ``finalists``
re-evaluates the archive's best gaits in ``select_worlds`` worlds of the selection stream and
keeps the best, and ``trials`` reports on the test stream, where nothing is chosen.

``gait-eval`` re-simulates stored parameters (same outputs but the convergence files); robot,
horizon, direction and slope come from the file unless given; its ``trials`` use the test
stream of the file's seed unless ``stream`` / ``seed`` say otherwise.
"""

from __future__ import annotations

import dataclasses
import json as jsonlib
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.errors import CheckpointError, ProblemError
from eaco_jax.gait.render import ensure_headless_gl
from eaco_jax.gait.stats import falls_interval
from eaco_jax.runs.base import (
    Built,
    RunKind,
    budget_of,
    check_out,
    check_settings,
    params_from,
    setting,
)
from eaco_jax.runs.tsp import PARAMS_HELP

ensure_headless_gl()  # before anything imports mujoco: its GL backend is fixed at import

BACKENDS = ("auto", "mjx", "native")
IMPLS = ("auto", "jax", "warp")
AGGREGATES = ("cvar", "worst", "mean")
IK_CHOICES = ("auto", "analytic", "generic")  # eaco_jax.gait.walk_engine.IK_CHOICES
CONSTRAINT_METHODS = ("epsilon", "deb", "penalty")
STREAM_NAMES = ("test", "selection", "optimisation")  # eaco_jax.gait.worlds.STREAMS


def _check_robust(robust: int, trials: int, penalty: str | None) -> None:
    from eaco_jax.errors import ConfigError

    for name, value in (("robust", robust), ("trials", trials)):
        if isinstance(value, bool) or int(value) != value or value < 0:
            raise ConfigError(f"{name} must be an integer >= 0, got {value!r}")
    if penalty not in (None, "power", "cot"):
        raise ConfigError(f"penalty={penalty!r} is not one of power, cot")


def check_noise(value: float | None) -> None:
    import math

    from eaco_jax.errors import ConfigError

    if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)
                              or not math.isfinite(value) or not 0 <= value <= 0.1):
        raise ConfigError(f"target_noise must be a number of radians in [0, 0.1], got {value!r}")


EVAL_HORIZON = 20.0
INIT_RADIUS = 0.15
"""``init`` search box: +/- this fraction of each parameter's range around the stored gait."""
#: the colony's switches ``eaco gait`` holds fixed (no option sets them) -> why: a --params
#: field only they would make act is refused with this reason
FIXED_SWITCHES = {"repair_steps": "no gradient repair on gait problems",
                  "refine_ants": "no SQP refinement on gait problems"}

METRIC_KEYS = ("fitness", "speed_mps", "distance_m", "fell", "drift_deg", "fall_time",
               "turn_deg_s")


ROBOT_HELP = ("robot: nao (humanoid), ant (quadruped), op3, go2, or the path of a robot spec "
              ".json (docs/robots.md)")


def absolute_spec(robot: str | None) -> str | None:
    """A robot given as a spec path, made absolute (a checkpoint resumes from any folder); a
    shipped robot's name as it is."""
    if robot is None or not (robot.endswith(".json") or "/" in robot or "\\" in robot):
        return robot
    return str(Path(robot).expanduser().absolute())


def pin_robot(checkpointing: Any, spec: Any) -> None:
    """Record the robot spec (path and sha256 of spec + MJCF) in a checkpoint's run info; a
    resumed run whose spec changed since is refused in one line."""
    if checkpointing is None:
        return
    info = checkpointing.run_info
    now = {"path": spec.source, "sha256": spec.digest}
    stored = info.get("robot_spec")
    if stored is None:
        info["robot_spec"] = now
    elif stored.get("sha256") != spec.digest:
        raise CheckpointError(
            f"the robot spec {spec.source} (or its MJCF) changed since this checkpoint was "
            f"written (sha256 {str(stored.get('sha256'))[:12]} then, {spec.digest[:12]} now); "
            "restore that spec, or start a new run without --checkpoint-dir")


#: the iteration budget of a run given neither --iterations, --max-evaluations nor --max-seconds
ITERATIONS = 25


@dataclasses.dataclass(frozen=True)
class GaitSettings:
    robot: str = setting("nao", ROBOT_HELP)
    backend: str = setting("auto", "physics: native (MuJoCo C, CPU default), mjx (GPU default) "
                           "or auto", choices=BACKENDS)
    ants: int = setting(16, "colony size (gaits simulated per iteration)")
    iterations: int | None = setting(None, f"colony iterations (default {ITERATIONS}; with "
                                     "--max-seconds alone, no cap: time ends the run)")
    horizon: float = setting(4.0, "seconds simulated per gait (the paper uses 20)")
    direction: float = setting(0.0, "desired walking direction in degrees, 0 = forward (+x)")
    slope: float = setting(0.0, "floor slope in degrees, uphill along +x")
    turn: str | None = setting(None, "score the heading turned instead of the distance: "
                               "left or right")
    seed: int = setting(0, "random seed")
    max_evaluations: int | None = setting(None, "evaluation budget (a hard cap; replaces "
                                          "--iterations)")
    max_seconds: float | None = setting(None, "stop after this many compute seconds")
    params: str | None = setting(None, PARAMS_HELP)
    out: str | None = setting("out/gait", "folder for best_gait.json, history.csv, plots, video")
    video: bool | None = setting(None, "render best_gait.mp4 offscreen (default: only where a "
                                 "display or a GPU exists)")
    init: str | None = setting(None, "warm start: search +/-15% of each range around this "
                               "stored gait (JSON)")
    impl: str = setting("auto", "MJX implementation: warp (MuJoCo Warp, CUDA), jax, or auto",
                        choices=IMPLS)
    robust: int = setting(0, "randomised worlds per ant (friction, masses, motors, latency, "
                          "noise, pushes); 0 = the nominal world only")
    aggregate: str = setting("cvar", "how the worlds' fitness combine", choices=AGGREGATES)
    penalty: str | None = setting(None, "energy-aware fitness: 'power' or 'cot'")
    penalty_weight: float = setting(0.0, "weight of the energy penalty")
    ik: str = setting("auto", "biped leg IK: analytic (the NAO's leg geometry), generic "
                      "(any leg chain, damped least squares on the MJCF) or auto",
                      choices=IK_CHOICES)
    trials: int = setting(0, "after the search: replay the best gait in this many randomised "
                          "worlds of the test stream (nothing is chosen on them)")
    constrained: bool = setting(False, "maximise speed under the motor (ten minutes' "
                                "endurance, current limit), slip, drift and fall constraints "
                                "(docs/gait_constraints.md)")
    constraint_method: str = setting("epsilon", "the colony's constraint handling with "
                                     "--constrained", choices=CONSTRAINT_METHODS)
    finalists: int = setting(0, "after the search: re-evaluate the archive's best gaits (this "
                             "many) in selection-stream worlds and keep the best; 0 = the "
                             "search's best")
    select_worlds: int = setting(64, "selection-stream worlds per finalist (with --finalists)")
    steer: bool = setting(False, "close the heading loop: the walk engine's turn rate holds "
                          "the torso's heading (eaco_jax.gait.steer defaults); the gait is "
                          "searched, selected and tested so")
    track_turn: bool = setting(False, "with --steer: the held heading turns at the gait's own "
                               "turn rate (Steering(track_turn=True)), so a turning gait "
                               "(--turn) can be steered")
    constraint_margin: float = setting(0.0, "with --constrained: the search's worlds must meet "
                                       "the endurance, slip and drift limits with this share "
                                       "of each limit's scale to spare (0.1: 5 C, 0.005 m/m, "
                                       "1 deg); selection and trials judge the limits themselves")
    target_noise: float | None = setting(None, "std of the randomised worlds' joint-target "
                                         "noise, rad (default 0.005; the 12-bit encoders' "
                                         "quantisation is 0.000443, docs/motors.md)")

    def __post_init__(self) -> None:
        from eaco_jax.errors import ConfigError

        check_settings(self, "ants", "iterations", "max_evaluations", "select_worlds")
        check_noise(self.target_noise)
        _check_robust(self.robust, self.trials, self.penalty)
        _check_robust(self.finalists, 0, None)
        if self.constraint_method != "epsilon" and not self.constrained:
            raise ConfigError(f"--constraint-method {self.constraint_method} needs "
                              "--constrained (an unconstrained gait search has no violation)")
        if self.constrained and self.penalty is not None:
            raise ConfigError("--constrained replaces the energy penalty: drop --penalty")
        if self.constraint_margin and not self.constrained:
            raise ConfigError("--constraint-margin needs --constrained")
        if self.track_turn and not self.steer:
            raise ConfigError("--track-turn needs --steer (it sets what the heading loop holds)")
        object.__setattr__(self, "robot", absolute_spec(self.robot))


@dataclasses.dataclass(frozen=True)
class GaitEvalSettings:
    params_file: str = setting("best_gait.json", "a stored gait (best_gait.json of `eaco gait`)",
                               positional=True, metavar="PARAMS.json")
    robot: str | None = setting(None, "robot name or spec .json (default: the file's)")
    backend: str = setting("auto", "native, mjx or auto", choices=BACKENDS)
    horizon: float | None = setting(None, "seconds to simulate (default: the file's, else 20)")
    out: str | None = setting(None, "folder for gait_eval.json, joint_angles.png and the video")
    video: bool | None = setting(None, "render best_gait.mp4 into --out (default: only where "
                                 "a display or a GPU exists)")
    impl: str = setting("auto", "MJX implementation: warp (MuJoCo Warp, CUDA), jax, or auto",
                        choices=IMPLS)
    trials: int = setting(0, "replay under this many randomised worlds of --stream; adds "
                          "'trials' to the record")
    stream: str = setting("test", "key stream of the trials' worlds: test (nothing is chosen "
                          "on them), selection or optimisation", choices=STREAM_NAMES)
    seed: int | None = setting(None, "run seed whose stream the trials draw from (default: the "
                               "file's seed, else 0)")
    accurate: bool = setting(False, "trials with MuJoCo's default solver settings")
    ik: str | None = setting(None, "biped leg IK: analytic, generic or auto (default: the "
                             "file's, else auto)")
    export: str | None = setting(None, "write the simulated run to this .npz (ctrl, qpos, qvel, "
                                 "the model's MJCF): it replays on plain mujoco")
    thermal: bool | None = setting(None, "integrate the motors' temperatures from 25 C along "
                                   "the walk (trace every second, plot, firmware limit; with "
                                   "--trials in those worlds, instead of the plain trials); "
                                   "default: on for a horizon of 60 s or more")
    steer: bool | None = setting(None, "close the heading loop as the gait was searched "
                                 "(default: the file's steering, else open loop)")
    target_noise: float | None = setting(None, "joint-target noise std of the trials' worlds, "
                                         "rad (default: the file's, else 0.005)")

    def __post_init__(self) -> None:
        check_settings(self)
        check_noise(self.target_noise)
        _check_robust(0, self.trials, None)
        object.__setattr__(self, "robot", absolute_spec(self.robot))


# --------------------------------------------------------------------------- parameter files
def read_params_file(path: str | Path) -> dict[str, Any]:
    """Load a stored gait (``best_gait.json`` / ``nao_best_gait.json``); one-line errors."""
    path = Path(path)
    if not path.is_file():
        raise ProblemError(f"parameter file {path} does not exist")
    try:
        data = jsonlib.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as err:
        raise ProblemError(f"parameter file {path} is not valid JSON ({err})") from None
    if not isinstance(data, dict) or not ("vector" in data or "params" in data):
        raise ProblemError(
            f"parameter file {path} needs a 'vector' list or a 'params' {{name: value}} object "
            "(as written by `eaco gait`)")
    return data


def params_vector(data: dict[str, Any], problem: Any, source: str) -> np.ndarray:
    """The parameter vector of a stored gait for ``problem`` (by name if given, else vector)."""
    names = problem.param_names
    if isinstance(data.get("params"), dict):
        missing = [n for n in names if n not in data["params"]]
        if missing:
            raise ProblemError(f"{source}: parameters {missing} missing for robot "
                             f"{problem.spec.name!r} (expects {', '.join(names)})")
        values = [data["params"][n] for n in names]
    else:
        values = data["vector"]
    try:
        vec = np.asarray(values, np.float32).reshape(-1)
    except (TypeError, ValueError):
        raise ProblemError(f"{source}: parameters must be numbers") from None
    if vec.shape != (len(names),):
        raise ProblemError(f"{source}: robot {problem.spec.name!r} needs {len(names)} parameters, "
                         f"got {vec.size}")
    if not np.all(np.isfinite(vec)):
        raise ProblemError(f"{source}: parameters must be finite")
    lo, hi = np.asarray(problem.lower, np.float64), np.asarray(problem.upper, np.float64)
    slack = 1e-6 * np.maximum(hi - lo, 1e-12)
    bad = np.flatnonzero((vec < lo - slack) | (vec > hi + slack))
    if bad.size:
        i = int(bad[0])
        raise ProblemError(f"{source}: {names[i]}={float(vec[i]):g} is outside the walk engine's "
                           f"range [{lo[i]:g}, {hi[i]:g}]")
    return vec


def video_wanted(video: bool | None) -> bool:
    """``video`` if given; by default only where a display or a GPU exists (a CPU renders
    slower than it searches). Says so on stderr when it switches the video off."""
    if video is not None:
        return bool(video)
    import os

    import jax

    if os.environ.get("DISPLAY") or jax.default_backend() == "gpu":
        return True
    print("note: no video by default on a CPU without a display; pass --video to render one "
          f"offscreen (MUJOCO_GL={os.environ.get('MUJOCO_GL', 'egl')}: egl or osmesa need "
          "libegl1 / libosmesa6)", file=sys.stderr)
    return False


def _stored(data: dict[str, Any], *keys: str) -> Any:
    for k in keys:
        if data.get(k) is not None:
            return data[k]
    return None


# --------------------------------------------------------------------------- outputs
def write_trajectory_outputs(folder: Path, problem: Any, sim: dict[str, Any], video: bool,
                             title: str) -> dict[str, str | None]:
    """``joint_angles.png`` and (if ``video``) ``best_gait.mp4`` of one simulated gait."""
    from eaco_jax import plots

    folder.mkdir(parents=True, exist_ok=True)
    legs, groups = leg_joints(sim["joints"], problem.spec)
    files: dict[str, str | None] = {"joint_angles": str(plots.joint_trajectories(
        sim["time"], legs, folder / "joint_angles.png", title=title, groups=groups))}
    files["video"] = write_video(folder / "best_gait.mp4", problem, sim["qpos"]) if video else None
    return files


def leg_joints(joints: dict[str, np.ndarray],
               spec: Any) -> tuple[dict[str, np.ndarray], tuple[str, ...]]:
    """The joints the paper plots and their groups: a biped's sagittal hip, knee and ankle
    joints of both legs (each leg chain's hip-pitch joint, the joints after it and its
    ankle-pitch joint, found by axis: :mod:`eaco_jax.gait.legs`), labelled so the group's name
    is in the label; other robots (quadrupeds) get every joint, grouped by name prefix."""
    if spec.gait == "biped":
        from eaco_jax.gait.legs import ROLES, leg_set

        legs = leg_set(spec)
        hip, ankle = ROLES.index("hip_pitch"), ROLES.index("ankle_pitch")
        out: dict[str, np.ndarray] = {}
        for k, names in enumerate(legs.joint_names):
            first, last = int(legs.role_index[k, hip]), int(legs.role_index[k, ankle])
            if first < 0 or last <= first:
                continue
            for i in range(first, last + 1):
                group = "Hip" if i == first else "Ankle" if i == last else "Knee"
                name = names[i]
                out[name if group.lower() in name.lower() else f"{group}: {name}"] = (
                    joints[name])
        if out:
            return out, ("Hip", "Knee", "Ankle")
    return dict(joints), tuple(dict.fromkeys(n.split("_")[0] for n in joints))


def write_video(path: Path, problem: Any, qpos: np.ndarray) -> str | None:
    """Render the trajectory offscreen; on a machine without OpenGL say so and return None."""
    from eaco_jax.gait.render import RenderUnavailable, render_video
    from eaco_jax.gait.rollout_native import native_model

    model = native_model(problem.spec, float(problem.slope_deg), problem.accuracy)
    try:
        with warnings.catch_warnings():  # ffmpeg runs as a subprocess (fork + exec): harmless
            warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called")
            return str(render_video(model, qpos, problem.spec.control_dt, path, fps=25.0,
                                    track_body=problem.spec.torso_body))
    except RenderUnavailable as err:
        print(f"note: video skipped, offscreen rendering is unavailable here: {err}",
              file=sys.stderr)
        return None


def fitness_history(history: dict[str, np.ndarray],
                    constrained: bool = False) -> dict[str, np.ndarray]:
    """The driver's cost history turned into fitness (metres walked), plus the rest;
    ``constrained``: the best speed (Deb's order: least violation first) and its violation."""
    if constrained:
        out = {"best_speed": -np.asarray(history["best_f"], np.float64),
               "best_violation": np.asarray(history["best_violation"], np.float64)}
        for k in ("diversity", "evaluations", "epsilon"):
            if k in history:
                out[k] = np.asarray(history[k])
        return out
    out = {"best_fitness": -np.asarray(history["best_cost"], np.float64),
           "iter_best_fitness": -np.asarray(history["iter_best_cost"], np.float64),
           "iter_mean_fitness": -np.asarray(history["iter_mean_cost"], np.float64)}
    for k in ("diversity", "evaluations"):
        if k in history:
            out[k] = np.asarray(history[k])
    return out


def _setting(problem: Any) -> dict[str, Any]:
    """The simulated setting shared by the gait and gait-eval records."""
    out = {"robot": problem.spec.name, "backend": problem.backend, "horizon": problem.horizon,
           "direction": problem.direction_deg, "slope": problem.slope_deg}
    if not problem.spec.builtin:  # a spec of the user's: what finds it again (gait-eval)
        out["robot_spec"] = problem.spec.source
        out["robot_sha256"] = problem.spec.digest
    if problem.turn is not None:
        out["turn"] = problem.turn
    if problem.ik != "auto":
        out["ik"] = problem.ik
    if problem.steering is not None:
        out["steering"] = problem.steering.record()
    return out


def _metrics(sim: dict[str, Any]) -> dict[str, Any]:
    """The record's metrics: distance rule and, for a robot with a motor datasheet, the energy
    and gait-quality record (power, CoT, envelope fractions, RMS torque per joint,
    overheating joints, slip, airborne fraction, foot gap) and, for every robot, the actuator
    envelope (:func:`eaco_jax.gait.quality.envelope`)."""
    out = {k: sim[k] for k in METRIC_KEYS}
    for k in ("quality", "envelope"):
        if k in sim:
            out[k] = sim[k]
    return out



# --------------------------------------------------------------------------- gait
def _problem(robot: str, backend: str, horizon: float, direction: float, slope: float,
             impl: str = "auto", robust: int = 0, aggregate: str = "cvar",
             penalty: str | None = None, penalty_weight: float = 0.0,
             turn: str | None = None, seed: int = 0, constrained: bool = False,
             ik: str = "auto", steering: Any = None, target_noise: float | None = None,
             margin: float = 0.0) -> Any:
    from eaco_jax.problems.gait import make_gait_problem

    cfg = (world_ranges(seed, target_noise, R=int(robust), aggregate=aggregate)
           if robust else None)
    return make_gait_problem(robot, backend=backend, horizon=float(horizon),
                             direction_deg=float(direction), slope_deg=float(slope), impl=impl,
                             robust=cfg, penalty=penalty, penalty_weight=float(penalty_weight),
                             turn=turn, constrained=constrained, ik=ik, steering=steering,
                             margin=float(margin))


def steering_of(on: bool | None, data: dict[str, Any] | None = None,
                track_turn: bool = False) -> Any:
    """The heading controller: ``on`` True -> the defaults (tracking the gait's own turn with
    ``track_turn``), False -> none, None -> the stored record's ``steering`` (``data``), else
    none."""
    from eaco_jax.gait.steer import Steering

    if on is None:
        return Steering.from_record((data or {}).get("steering"))
    return Steering(track_turn=track_turn) if on else None


def narrowed_around(problem: Any, init: str | Path) -> tuple[Any, np.ndarray]:
    """``problem`` with its box narrowed to +/- ``INIT_RADIUS`` of each range around the
    stored gait in the file ``init`` (clipped to the box), and that gait's vector."""
    import jax.numpy as jnp

    init_vec = params_vector(read_params_file(init), problem, str(init))
    full_lo, full_hi = np.asarray(problem.lower), np.asarray(problem.upper)
    half = INIT_RADIUS * (full_hi - full_lo)
    lo = np.maximum(full_lo, init_vec - half).astype(np.float32)
    hi = np.minimum(full_hi, init_vec + half).astype(np.float32)
    return problem.replace(lower=jnp.asarray(lo), upper=jnp.asarray(hi)), init_vec


def build(s: GaitSettings) -> Built:
    """The gait problem (narrowed around ``init`` if given) and a gradient-free colony."""
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO

    problem = _problem(s.robot, s.backend, s.horizon, s.direction, s.slope, s.impl, s.robust,
                       s.aggregate, s.penalty, s.penalty_weight, s.turn, s.seed, s.constrained,
                       ik=s.ik, steering=steering_of(s.steer, track_turn=s.track_turn),
                       target_noise=s.target_noise,
                       margin=s.constraint_margin)
    search = problem
    extra: dict[str, Any] = {"full_problem": problem}
    if s.init is not None:
        search, extra["init_vec"] = narrowed_around(problem, s.init)
    # the simulation is not differentiable: no SQP refinement ants, no gradient repair
    ants = int(s.ants)
    strategy = ContinuousEACO(num_ants=ants, archive_size=max(2, (3 * ants) // 2),
                              refine_ants=0, repair_steps=0,
                              constraint_method=s.constraint_method)
    params = params_from(strategy, search, s.params, fixed=FIXED_SWITCHES, command="eaco gait")
    return Built(search, strategy, params, budget_of(s, s.iterations, {"iterations": ITERATIONS}),
                 extra=extra)


def row_metrics(built: Built, result: Any, row: int) -> dict[str, Any]:
    if getattr(built.problem, "constrained", False):
        return {"speed": -float(np.asarray(result.f).reshape(-1)[row]),
                "violation": float(np.asarray(result.violation).reshape(-1)[row]),
                "feasible": bool(np.asarray(result.feasible).reshape(-1)[row])}
    return {"fitness": -float(np.asarray(result.best_cost).reshape(-1)[row])}


def select_finalists(problem: Any, archive: np.ndarray, k: int, n: int,
                     seed: int, config: Any = None) -> tuple[np.ndarray, dict[str, Any]]:
    """The best of the archive's first ``k`` gaits (the colony keeps its archive best first)
    re-evaluated in ``n`` worlds of the selection stream of ``seed``: by Deb's rule (least
    violation, then speed) for a constrained problem, else by the aggregated fitness.
    Returns the chosen gait and the ``selection`` record (stream, worlds, per finalist).
    World ranges: the problem's ``robust``, else ``config``, else the defaults."""
    import jax
    import jax.numpy as jnp

    from eaco_jax.gait.worlds import RobustConfig, stream_key

    cand = np.asarray(archive, np.float32)[:k]
    cfg = problem.robust or config or RobustConfig(seed=int(seed))
    prob = problem.replace(robust=dataclasses.replace(cfg, R=int(n)))
    worlds = prob.worlds(stream_key(int(seed), "selection", 0), int(n))
    x = jnp.clip(jnp.asarray(cand), prob.lower, prob.upper)
    if getattr(prob, "constrained", False):
        from eaco_jax.gait import constraints as gc

        speed, _, g = jax.jit(prob.constraints)(x, worlds)
        score, viol = np.asarray(speed, np.float64), np.asarray(gc.violation(g), np.float64)
    else:
        res = jax.jit(lambda x, w: prob.rollout(x, w))(x, worlds)
        score = np.asarray(aggregate_fitness(res["fitness"], cfg), np.float64)
        viol = np.zeros_like(score)
    score = np.where(np.isfinite(score), score, -np.inf)
    best = int(np.lexsort((-score, viol))[0])
    rows = [{"score": float(a), "violation": float(b)} for a, b in zip(score, viol, strict=True)]
    return cand[best], {"stream": "selection", "seed": int(seed), "worlds": int(n),
                        "finalists": rows, "chosen": best,
                        "score": "speed_mps" if prob.constrained else "fitness"}


def aggregate_fitness(fitness: Any, cfg: Any) -> Any:
    """Per-gait fitness from per-world fitness ``(m, R)`` under ``cfg``'s aggregate."""
    from eaco_jax.gait.fitness import aggregate

    return aggregate(fitness, cfg.aggregate, cfg.alpha)


def run(s: GaitSettings, *, progress: bool = False, checkpointing: Any = None) -> dict[str, Any]:
    """Optimise a gait; write the outputs to ``s.out``; returns the JSON record."""
    from eaco_jax.driver.minimize import minimize

    check_out(s.out)
    built = build(s)
    problem = built.extra["full_problem"]
    pin_robot(checkpointing, problem.spec)
    t0 = time.perf_counter()
    result = minimize(built.problem, built.strategy, seed=int(s.seed), progress=progress,
                      checkpointing=checkpointing, params=built.params, **built.budget)
    best = np.asarray(result.best_solution, np.float32)
    selection = None
    if s.finalists:
        best, selection = select_finalists(problem, np.asarray(result.state.archive_x),
                                           int(s.finalists), int(s.select_worlds), int(s.seed),
                                           world_ranges(int(s.seed), s.target_noise))
    sim = problem.simulate(best, record=True)
    seconds = time.perf_counter() - t0
    history = fitness_history(result.history, problem.constrained)
    record: dict[str, Any] = {
        **_setting(problem),
        "ants": int(s.ants),
        "seed": int(s.seed),
        "iterations": int(result.iterations),
        "evaluations": int(np.asarray(result.evaluations)),
        "stop_reason": result.stop_reason,
        **_metrics(sim),
        "search_fitness": float(-np.asarray(result.best_cost)),
        **({"selection": selection} if selection is not None else {}),
        "params": problem.params_dict(best),
        "vector": best.tolist(),
        "init": s.init,
        "seconds": seconds,
        "compile_seconds": float(result.compile_seconds),
        "seconds_per_iteration": float(result.seconds_per_iteration),
        "history_best": history["best_speed" if problem.constrained
                                else "best_fitness"].tolist(),
        "out": s.out,
    }
    if "init_vec" in built.extra:
        record["init_fitness"] = problem.simulate(built.extra["init_vec"], record=False)["fitness"]
    if s.robust:
        record["robust"] = {"R": int(s.robust), "aggregate": s.aggregate, "seed": int(s.seed),
                            "stream": "optimisation",
                            "target_noise": float(problem.robust.target_noise)}
    if problem.constrained:
        record["constraint_method"] = s.constraint_method
        record["constraint_margin"] = float(s.constraint_margin)
        record["history_violation"] = history["best_violation"].tolist()
        record["search"] = {"speed": -float(np.asarray(result.f)),
                            "violation": float(np.asarray(result.violation)),
                            "feasible": bool(np.asarray(result.feasible))}
        record["constraints"] = constraints_record(problem, best, int(s.seed), selection)
    if s.trials:
        from eaco_jax.gait.validate import evaluate_trials

        record["trials"] = evaluate_trials(problem, best, n=int(s.trials), seed=int(s.seed),
                                           stream="test",
                                           config=problem.robust or world_ranges(
                                               int(s.seed), s.target_noise))
    if s.out is not None:
        from eaco_jax import plots
        from eaco_jax.outputs import write_history_csv, write_json

        folder = Path(s.out)
        folder.mkdir(parents=True, exist_ok=True)
        write_history_csv(folder / "history.csv", history)
        if problem.constrained:
            plots.convergence(history, folder / "convergence.png",
                              keys=("best_speed", "best_violation"),
                              ylabel="speed [m/s] / violation",
                              title=f"{problem.name}: constrained ({problem.horizon:g} s)")
        else:
            plots.convergence(history, folder / "convergence.png",
                              keys=("best_fitness", "iter_mean_fitness"), ylabel="fitness [m]",
                              title=f"{problem.name}: fitness ({problem.horizon:g} s horizon)")
        files = write_trajectory_outputs(
            folder, problem, sim, video_wanted(s.video),
            title=f"{problem.spec.name}: best gait, {sim['speed_mps']:.2f} m/s")
        record["files"] = {"best_gait": str(folder / "best_gait.json"),
                           "history": str(folder / "history.csv"),
                           "convergence": str(folder / "convergence.png"), **files}
        write_json(folder / "best_gait.json", record)
    return record


def constraints_record(problem: Any, best: np.ndarray, seed: int,
                       selection: dict[str, Any] | None) -> dict[str, Any]:
    """The kept gait's constraints (value, limit, margin, holds) in the worlds that chose it:
    the selection stream's (with finalists), else the key-less optimisation worlds that
    ``host_check`` uses (the nominal world without randomisation)."""
    if selection is not None:
        from eaco_jax.gait.worlds import stream_key

        n = int(selection["worlds"])
        ranges = problem.robust or world_ranges(seed, None)
        prob = problem.replace(robust=dataclasses.replace(ranges, R=n))
        rep = prob.report(best, prob.worlds(stream_key(seed, "selection", 0), n))
        return {"stream": "selection", **rep}
    worlds = problem.worlds() if problem.robust is not None else None
    return {"stream": "optimisation" if worlds is not None else "nominal",
            **problem.report(best, worlds)}


# --------------------------------------------------------------------------- gait-eval
def build_eval(s: GaitEvalSettings) -> Built:
    data = read_params_file(s.params_file)
    robot = s.robot or _stored(data, "robot_spec", "robot") or "nao"
    horizon = s.horizon
    if horizon is None:
        horizon = float(_stored(data, "horizon", "verify_horizon") or EVAL_HORIZON)
    direction = float(_stored(data, "direction", "direction_deg") or 0.0)
    slope = float(_stored(data, "slope", "slope_deg") or 0.0)
    turn = _stored(data, "turn")
    ik = s.ik or _stored(data, "ik") or "auto"
    problem = _problem(str(robot), s.backend, float(horizon), direction, slope, s.impl,
                       turn=turn, ik=str(ik), steering=steering_of(s.steer, data))
    vec = params_vector(data, problem, str(s.params_file))
    seed = s.seed if s.seed is not None else _stored(data, "seed")
    if seed is None and isinstance(data.get("optimisation"), dict):
        seed = data["optimisation"].get("seed")
    noise = s.target_noise
    if noise is None and isinstance(data.get("robust"), dict):
        noise = data["robust"].get("target_noise")
    check_noise(noise)
    return Built(problem, None, None, {}, extra={"vector": vec, "seed": int(seed or 0),
                                                 "target_noise": noise})


def world_ranges(seed: int, target_noise: float | None, **fields: Any) -> Any:
    """A :class:`~eaco_jax.gait.worlds.RobustConfig` of run seed ``seed`` with ``fields``; the
    default ranges but ``target_noise`` where given (None: the default noise)."""
    from eaco_jax.gait.worlds import RobustConfig

    noise = {} if target_noise is None else {"target_noise": float(target_noise)}
    return RobustConfig(seed=int(seed), **fields, **noise)


def run_eval(s: GaitEvalSettings, *, progress: bool = False,
             checkpointing: Any = None) -> dict[str, Any]:
    """Re-simulate a stored gait; returns the JSON record and writes ``s.out`` if set."""
    check_out(s.out)
    built = build_eval(s)
    problem, vec = built.problem, built.extra["vector"]
    thermal = thermal_wanted(s.thermal, problem)  # refuses before any simulation
    cfg = world_ranges(built.extra["seed"], built.extra["target_noise"])
    t0 = time.perf_counter()
    sim = problem.simulate(vec, record=s.out is not None)
    record: dict[str, Any] = {
        **_setting(problem),
        **_metrics(sim),
        "params": problem.params_dict(vec),
        "vector": vec.tolist(),
        "source": str(s.params_file),
        "seconds": time.perf_counter() - t0,
        "out": s.out,
    }
    if thermal:
        from eaco_jax.gait.thermal_walk import thermal_walk

        record["thermal"] = thermal_walk(
            problem.replace(accuracy="accurate") if s.accurate else problem, vec,
            n=int(s.trials), seed=built.extra["seed"], stream=s.stream, config=cfg)
    elif s.trials:
        from eaco_jax.gait.validate import evaluate_trials

        record["trials"] = evaluate_trials(problem, vec, n=int(s.trials), accurate=s.accurate,
                                           seed=built.extra["seed"], stream=s.stream,
                                           config=cfg)
    if s.export is not None:
        from eaco_jax.gait.validate import export_run

        record["export"] = str(export_run(problem, vec, s.export))
    if s.out is not None:
        from eaco_jax.outputs import write_json

        folder = Path(s.out)
        files = write_trajectory_outputs(
            folder, problem, sim, video_wanted(s.video),
            title=f"{problem.spec.name}: {Path(s.params_file).name}, {sim['speed_mps']:.2f} m/s")
        if thermal:
            files["temperatures"] = str(temperature_plot(
                record["thermal"], folder / "temperatures.png",
                title=f"{problem.spec.name}: {Path(s.params_file).name}"))
        record["files"] = {"eval": str(folder / "gait_eval.json"), **files}
        write_json(folder / "gait_eval.json", record)
    return record


THERMAL_MIN_HORIZON = 60.0
"""gait-eval integrates the motors' temperatures by default from this horizon (s) on."""


def thermal_wanted(thermal: bool | None, problem: Any) -> bool:
    """Whether gait-eval runs the thermal walk: as asked, else for a horizon of at least
    :data:`THERMAL_MIN_HORIZON` on a robot with electrical motor data."""
    from eaco_jax.gait.motors import motor_model

    has = motor_model(problem.spec) is not None
    if thermal and not has:
        raise ProblemError(f"robot {problem.spec.name!r} has no electrical motor data: no "
                           "thermal walk (drop --thermal)")
    if thermal is None:
        return has and problem.horizon >= THERMAL_MIN_HORIZON
    return bool(thermal)


def temperature_plot(rec: dict[str, Any], path: Path, title: str) -> Path:
    """Winding temperature of each leg joint (the hotter of left and right, the hottest world)
    against time, with the firmware limit: ``temperatures.png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from eaco_jax.gait.thermal_walk import LEG_ROLES

    t = np.asarray(rec["trace"]["t_s"]) / 60.0
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    wind = rec["trace"]["winding_c"]
    for role in LEG_ROLES:
        rows = [np.asarray(v) for k, v in wind.items() if k.endswith(role)]
        if rows:
            ax.plot(t, np.max(rows, axis=0), lw=1.3, label=role)
    ax.axhline(rec["firmware_limit_c"], color="k", ls="--", lw=1.0, label="firmware limit")
    ax.set_xlabel("time walking [min]")
    ax.set_ylabel("winding [C]")
    where = "nominal world" if rec["worlds"] == 1 else (
        f"hottest of {rec['worlds']} {rec['stream']}-stream worlds")
    ax.set_title(f"{title} ({where})", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def thermal_line(rec: dict[str, Any]) -> str:
    """``thermal (N worlds, stream, H s): ...`` of a thermal-walk record."""
    from eaco_jax.gait.thermal_walk import leg_table

    legs = leg_table(rec)
    hot = max(legs, key=lambda k: legs[k]["winding_end_c"]) if legs else None
    limit = (f"firmware limit {rec['firmware_limit_c']:.0f} C reached after "
             f"{rec['first_limit_s']:.0f} s in {rec['worlds_reaching_limit']} world(s)"
             if rec["limit_reached"] else
             f"no winding reaches the firmware limit {rec['firmware_limit_c']:.0f} C")
    worst = (f"; hottest leg joint {hot} {legs[hot]['winding_end_c']:.0f} C at the end"
             if hot else "")
    lo, hi = rec["fall_rate_ci95"]
    return (f"thermal ({rec['worlds']} {rec['stream']} world{'s' if rec['worlds'] != 1 else ''}"
            f", {rec['horizon_s']:g} s): {limit}{worst}; {rec['falls']} falls (95% CI "
            f"{100 * lo:.2g}-{100 * hi:.2g}%), {rec['speed_mps_mean']:.3f} m/s, peak current "
            f"{rec['peak_current_max_frac']:.2f} x limit, {_walking_worst(rec)}")


def _walking_worst(rec: dict[str, Any]) -> str:
    """Worst slip and drift of a thermal record, over the worlds that did not fall where some
    fell (a fallen robot's slide says nothing about the gait)."""
    w = rec.get("walking_worlds")
    if w is None or w["worlds"] == rec["worlds"]:
        return f"slip {rec['slip_per_m_max']:.3f} m/m, drift {rec['drift_deg_max']:.1f} deg"
    return (f"over the {w['worlds']} walking worlds slip {w['slip_per_m_max']:.3f} m/m, drift "
            f"{w['drift_deg_max']:.1f} deg")


def trials_line(trials: dict[str, Any]) -> str:
    """``trials (test stream): N worlds, F falls (x%, 95% CI a-b%), speed m +/- c m/s`` of a
    trials record."""
    n, falls = int(trials["n"]), int(trials["falls"])
    lo, hi = falls_interval(falls, n)
    stream = trials.get("stream")
    head = f"trials ({stream} stream)" if stream else "trials"
    broken = [k for k, row in (trials.get("constraints") or {}).items() if not row["holds"]]
    tail = ("" if "constraints" not in trials else
            "; constraints (worst world): " + ("all hold" if not broken else
                                                 "violated " + ", ".join(broken)))
    return (f"{head}: {n} worlds, {falls} fall{'' if falls == 1 else 's'} "
            f"({100 * falls / n:.1f}%, 95% CI {100 * lo:.1f}-{100 * hi:.1f}%), speed "
            f"{trials['speed_mps_mean']:.3f} +/- {trials['speed_mps_ci95']:.3f} m/s "
            "(mean, 95% CI)" + tail)


def constraints_line(c: dict[str, Any]) -> str:
    """``constraints (stream, n worlds): feasible | violated: ...`` with each constraint's value
    against its limit."""
    parts = []
    for name, row in c["constraints"].items():
        mark = "ok" if row["holds"] else "VIOLATED"
        parts.append(f"{name} {row['value']:.3g} (limit {row['limit']:.3g} {row['unit']}, "
                     f"{mark})")
    state = "all hold" if c["feasible"] else f"violation {c['violation']:.3g}"
    return (f"constraints ({c['stream']}, {c['worlds']} world{'s' if c['worlds'] != 1 else ''}"
            f"): {state}; " + "; ".join(parts))


def motors_line(q: dict[str, Any]) -> str:
    """One line on the motors: the first joint to reach the firmware limit in continuous
    walking (or none), the hottest steady state, peak current against the limit, electrical
    energy and CoT."""
    table = q["motors"]
    hot = min(table, key=lambda j: table[j]["endurance_min"] if table[j]["endurance_min"]
              is not None else float("inf"))
    first = table[hot]["endurance_min"]
    when = (f"{hot} reaches the firmware limit after {first:.1f} min" if first is not None
            else "no joint reaches the firmware limit")
    steady = max(table, key=lambda j: table[j]["winding_steady_c"])
    return (f"motors: {when}; hottest steady state {steady} "
            f"{table[steady]['winding_steady_c']:.0f} C; peak current "
            f"{q['peak_current_max_frac']:.2f} x limit; electrical "
            f"{q['electrical_energy_j']:.0f} J, CoT {q['electrical_cot']:.2f}")


def summary(record: dict[str, Any]) -> str:
    """The run in one line, then the trials (``--trials``) and the exported file
    (``--export``) if there are any."""
    fell = f"fell at {record['fall_time']:.1f} s" if record["fell"] else "no fall"
    if record.get("turn"):
        line = (f"{record['robot']} ({record['backend']}, {record['horizon']:g} s, turning "
                f"{record['turn']}): {record['turn_deg_s']:.1f} deg/s, {fell}, "
                f"fitness {record['fitness']:.1f} deg")
    else:
        q = record.get("quality")
        energy = (f", CoT {q['cost_of_transport']:.2f}, power {q['mean_power_w']:.0f} W mean "
                  f"/ {q['peak_power_w']:.0f} W peak" if q else "")
        line = (f"{record['robot']} ({record['backend']}, {record['horizon']:g} s): "
                f"speed {record['speed_mps']:.3f} m/s, distance {record['distance_m']:.3f} m, "
                f"{fell}, drift {record['drift_deg']:.1f} deg, fitness "
                f"{record['fitness']:.3f}{energy}")
    lines = [line]
    q = record.get("quality") or {}
    if record.get("envelope"):
        from eaco_jax.gait.quality import envelope_table

        lines.append(envelope_table(record["envelope"]))
    if "motors" in q and not record.get("thermal"):  # the thermal walk's figures supersede
        lines.append(motors_line(q))
    if record.get("constraints"):
        lines.append(constraints_line(record["constraints"]))
    if record.get("trials"):
        lines.append(trials_line(record["trials"]))
    if record.get("thermal"):
        lines.append(thermal_line(record["thermal"]))
    if record.get("export"):
        lines.append(f"export: wrote {record['export']}")
    return "\n".join(lines)


KIND = RunKind("gait", GaitSettings, build, run, row_metrics, summary)
EVAL_KIND = RunKind("gait-eval", GaitEvalSettings, build_eval, run_eval, None, summary,
                   resumable=False)
