"""The ``walk`` run: plan a route through a scene, then let the NAO walk it on native MuJoCo
or on MJX (``--backend mjx``: every world in one batched, jitted call, ``--impl warp`` for MuJoCo
Warp on a GPU; :mod:`eaco_jax.gait.walk_route_mjx`).

``eaco walk SCENE`` (a scene JSON file, ``default`` or ``random:SEED``) plans the least walking
time route with ``--planner`` (the path colony, the path GA or the exact yardstick) and walks it
with the path-following controller of :mod:`eaco_jax.gait.walk_route` in the scene's MuJoCo
model (:mod:`eaco_jax.gait.scene_world`): once in the nominal world, or in ``--worlds N``
randomised worlds of ``--stream`` (success rate with its Clopper-Pearson 95% interval).

The route is planned for the robot that walks it: obstacles grown by ``--clearance`` (the
NAO's half-width, 0.25 m with its arms and feet, plus a tracking margin) where that exceeds the
scene's, and with ``--ramps avoid`` every ramp planned around as an obstacle: a ramp is built
as a wedge whose raised sides are steps the NAO cannot climb, and it can be entered from its
low end only (``--ramps cross`` plans across ramps as the scene's cost model allows).
The planner prices what the controller does (``--speeds walk``, the default): the flat speed
and the yaw rate of the gait library's ``planning`` entry, fitted to this controller's walks on
tuning scenes; ``--speeds nao`` prices the path planner's own gait table (turning on the spot).
The walk simulates the robot spec's motor model (``--motors spec``, the default: limits in
the physics, interpolated targets; :func:`~eaco_jax.gait.walk_route.motor_physics`), as the
gait rollouts do; ``--motors servo`` walks the MJCF's position servos with held targets.
Outputs in ``--out``: ``walk.json`` and ``walk.png`` (top view: planned and walked routes).
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.runs.base import Built, RunKind, check_out, check_settings, setting

#: the help's note on a controller setting a gait library may choose for itself
LIB = " (default: the gait library's, else {:g})"

PLANNERS = ("path-eaco", "path-ga", "optimal")
BACKENDS = ("native", "mjx")
IMPLS = ("jax", "warp")
RAMP_MODES = ("avoid", "cross")
MOTORS = ("servo", "spec")
PLAN_ITERATIONS = 150


@dataclasses.dataclass(frozen=True)
class WalkSettings:
    scene: str = setting("default", "scene JSON file, 'default' or 'random:SEED'",
                         positional=True, metavar="SCENE")
    planner: str = setting("path-eaco", "who plans the route: the path colony, the path GA "
                           "or the exact time-optimal yardstick", choices=PLANNERS)
    plan_seed: int = setting(0, "seed of the planner")
    plan_iterations: int = setting(PLAN_ITERATIONS, "planner iterations")
    clearance: float = setting(0.4, "planning clearance [m] around obstacles (the scene's if "
                               "larger): the NAO's half-width 0.25 m plus a tracking margin")
    ramps: str = setting("avoid", "plan around ramps (their raised sides are steps) or "
                         "across them", choices=RAMP_MODES)
    worlds: int = setting(0, "walk in this many randomised worlds of --stream (0: the "
                          "nominal world only)")
    seed: int = setting(0, "run seed whose world stream the randomised worlds draw from")
    stream: str = setting("test", "key stream of the worlds: test (nothing is chosen on "
                          "them), selection or optimisation",
                          choices=("test", "selection", "optimisation"))
    max_time: float | None = setting(None, "seconds a walk may last (default: 1.6 x the "
                                     "planned time + 10 s)")
    gaits: str = setting("nao_constrained", "gait library: a shipped name (nao_constrained: the "
                         "stored flat gait under the motor constraints; nao: the open-loop "
                         "gait) or a JSON file")
    speeds: str = setting("walk", "what the planner prices: 'walk' (the gait library's "
                          "speed and yaw rate of this controller's walks) or a gait speed "
                          "table (a shipped name such as 'nao', or a JSON file)")
    lookahead: float = setting(0.9, "controller: target distance ahead on the segment [m]")
    capture: float = setting(0.3, "controller: a waypoint is reached within this [m]")
    turn_deg: float | None = setting(None, "controller: turn on the spot above this heading "
                                     "error (180: never)" + LIB.format(180))
    resume_deg: float | None = setting(None, "controller: stop turning below this heading error"
                                       + LIB.format(20))
    steer_gain: float | None = setting(None, "controller: forward gait's turn rate per heading "
                                       "error" + LIB.format(1.2))
    max_steer: float | None = setting(None, "controller: largest turn rate of the forward gait "
                                      "[rad/s]" + LIB.format(0.8))
    slow_deg: float | None = setting(None, "controller: shorten the forward step above this "
                                     "heading error" + LIB.format(15))
    stop_deg: float | None = setting(None, "controller: ... to --min-step of its length at this "
                                     "error" + LIB.format(120))
    min_step: float | None = setting(None, "controller: shortest forward step, a fraction of the"
                                     " gait's" + LIB.format(0.35))
    goal_turn_deg: float | None = setting(None, "controller: within --lookahead of the goal, turn"
                                          " on the spot above this heading error (180: "
                                          "never)" + LIB.format(60))
    bend_distance: float = setting(0.0, "controller: within this distance of a bend [m], "
                                   "shorten the forward step as for a heading error of the "
                                   "bend's turn scaled by the distance covered (0: off)")
    blend_cycles: float = setting(0.5, "controller: step cycles a gait change blends over")
    start_ramp_s: float | None = setting(None, "controller: over the first this many seconds "
                                         "cap the forward step at the elapsed share of them, "
                                         "so the walk starts slow (with library cells: slowest "
                                         "first; 0: off)" + LIB.format(0))
    backend: str = setting("native", "physics: native MuJoCo (one world at a time) or MJX "
                           "(the nominal and every randomised world in one batched call)",
                           choices=BACKENDS)
    impl: str = setting("jax", "MJX implementation (--backend mjx): jax, or warp (MuJoCo "
                        "Warp, CUDA only)", choices=IMPLS)
    motors: str = setting("spec", "motor model of the walk: the robot spec's (current limit, "
                          "back-EMF, gear efficiency, targets interpolated between control "
                          "steps) as the gait rollouts simulate it, or the scene model's "
                          "position servos with held targets (claim "
                          "walk-tuning-motors-spec-successes)", choices=MOTORS)
    out: str | None = setting(None, "folder for walk.json and walk.png")

    def __post_init__(self) -> None:
        check_settings(self, "plan_iterations")
        if self.worlds < 0:
            raise ConfigError(f"worlds must be >= 0, got {self.worlds}")
        if not (math.isfinite(self.clearance) and self.clearance >= 0):
            raise ConfigError(f"clearance must be a number >= 0, got {self.clearance}")
        if self.max_time is not None and not (math.isfinite(self.max_time)
                                              and self.max_time > 0):
            raise ConfigError(f"max_time must be a number > 0, got {self.max_time}")
        self.controller()  # one line for bad controller settings

    def walk_seconds(self, planned: float) -> float:
        """How long a walk of a route planned at ``planned`` seconds may last: ``max_time``,
        or 1.6 x the planned time + 10 s."""
        return self.max_time or 1.6 * planned + 10.0

    def controller(self, gaits: Any = None):
        """The walk controller of these settings; a field of ``LIBRARY_CONTROLLER`` left
        unset (None) takes the value ``gaits`` (a
        :class:`~eaco_jax.gait.walk_route.WalkGaits`) chose for itself, else the
        :class:`~eaco_jax.gait.walk_route.Controller` default."""
        from eaco_jax.gait.walk_route import LIBRARY_CONTROLLER, Controller

        chosen = dict(gaits.controller) if gaits is not None else {}
        own = {f: getattr(self, f) for f in LIBRARY_CONTROLLER}
        return Controller(lookahead=self.lookahead, capture=self.capture,
                          bend_distance=self.bend_distance, blend_cycles=self.blend_cycles,
                          **{**chosen, **{f: v for f, v in own.items() if v is not None}})


def planning_scene(scene: Any, clearance: float, ramps: str) -> Any:
    """The scene the route is planned on: clearance raised to ``clearance``; with
    ``ramps="avoid"`` each ramp an obstacle of its footprint."""
    from eaco_jax.problems.scenes import Obstacle

    out = dataclasses.replace(scene, clearance=max(scene.clearance, clearance))
    if ramps == "avoid" and scene.ramps:
        out = dataclasses.replace(out, ramps=(), obstacles=scene.obstacles + tuple(
            Obstacle(r.polygon, 0.1) for r in scene.ramps))
    return out


def planning_speeds(speeds: str, gaits: str) -> Any:
    """The gait speed table the route is planned with: ``"walk"`` takes the flat speed and
    the yaw rate from the gait library's ``planning`` entry (what this controller's walks
    measured), the slope rows scaled from the default table by the same flat-speed ratio;
    anything else is a gait speed table (:func:`~eaco_jax.problems.scenes.load_gait_speeds`)."""
    from eaco_jax.problems.scenes import load_gait_speeds

    if speeds != "walk":
        return load_gait_speeds(speeds)
    from eaco_jax.gait.walk_route import load_walk_gaits

    plan = load_walk_gaits(gaits).planning
    if plan is None:
        raise ConfigError(f"gait library {gaits!r} has no 'planning' entry (speed_mps, "
                          "yaw_rate_deg_s); pass --speeds nao or a gait speed table")
    base = load_gait_speeds()
    scale = float(plan["speed_mps"]) / float(base.speed(0.0))
    return dataclasses.replace(
        base, speeds_mps=tuple(v * scale for v in base.speeds_mps),
        yaw_rate_deg_s=float(plan["yaw_rate_deg_s"]),
        claims=tuple(c if d == 0.0 else "" for c, d in zip(
            (str(plan.get("speed_claim", "")),) * len(base.slopes_deg), base.slopes_deg,
            strict=True)),
        yaw_claim=str(plan.get("yaw_claim", "")),
        source=f"walk gait library {gaits!r} planning entry; slope rows scaled from the "
               f"default table ({base.source})")


def build(s: WalkSettings) -> Built:
    """The planning problem (the scene for the walking robot) and the planner; a scene
    refused only at the walk's larger clearance (the goal walled in, the start on a grown
    obstacle) says so, naming ``--clearance``."""
    from eaco_jax.problems.scenes import build_problem, load_scene
    from eaco_jax.strategies import get

    scene = load_scene(s.scene)
    speeds = planning_speeds(s.speeds, s.gaits)
    try:
        problem = build_problem(planning_scene(scene, s.clearance, s.ramps), speeds)
    except ProblemError as err:
        if s.clearance <= scene.clearance:
            raise
        try:  # the scene's own clearance: does only the walk's larger one refuse it?
            build_problem(planning_scene(scene, scene.clearance, s.ramps), speeds)
        except ProblemError:
            raise err from None
        raise ProblemError(f"{err} (eaco walk plans at --clearance {s.clearance:g} m, above "
                           f"the scene's {scene.clearance:g} m: pass a smaller --clearance, "
                           "not below the NAO's half-width 0.25 m)") from None
    strategy = None if s.planner == "optimal" else get(s.planner)
    params = None if strategy is None else strategy.default_params(problem)
    return Built(problem, strategy, params, {"iterations": int(s.plan_iterations)})


def plan(s: WalkSettings, built: Built) -> tuple[np.ndarray, float, dict[str, Any]]:
    """Waypoints ``(k, 2)``, their planned walking time [s] and the planner's record."""
    problem = built.problem
    if built.strategy is None:
        route = np.asarray(problem.coords, np.float64)[list(problem.optimal_route)]
        return route, float(problem.optimum), {"planner": "optimal"}
    from eaco_jax.driver.minimize import minimize

    result = minimize(problem, built.strategy, seed=int(s.plan_seed), params=built.params,
                      **built.budget)
    best = np.asarray(result.best_solution)
    cost = float(result.best_cost)
    return (np.asarray(problem.waypoints(best), np.float64), cost,
            {"planner": s.planner, "evaluations": int(result.evaluations),
             "gap_percent": 100.0 * (cost / problem.optimum - 1.0),
             "seconds": result.seconds})


def _success_stats(walks: list[dict[str, Any]], planned: float) -> dict[str, Any]:
    from eaco_jax.gait.stats import falls_interval

    n = len(walks)
    ok = [w for w in walks if w["success"]]
    ratio = [w["reach_time_s"] / planned for w in ok]
    return {
        "n": n, "successes": len(ok), "success_rate": len(ok) / max(n, 1),
        "success_rate_ci95": list(falls_interval(len(ok), n)),
        "falls": sum(w["fell"] for w in walks), "contacts": sum(w["contact"] for w in walks),
        "not_reached": sum(not w["reached"] for w in walks),
        "walked_over_planned_mean": float(np.mean(ratio)) if ratio else None,
        "walked_over_planned_max": float(np.max(ratio)) if ratio else None,
        "within_20_percent": sum(abs(r - 1.0) <= 0.2 for r in ratio),
        "closest_approach_m_min_success": (min(w["closest_approach_m"] for w in ok)
                                           if ok else None),
    }


def run(s: WalkSettings, *, progress: bool = False, checkpointing: Any = None) -> dict[str, Any]:
    """Plan, then walk; returns the JSON record and writes ``s.out`` if set."""
    import jax

    from eaco_jax.gait import scene_world as sw
    from eaco_jax.gait import walk_route as wr
    from eaco_jax.gait.robot import load_robot

    if checkpointing is not None:
        raise ConfigError("eaco walk has no checkpoints; run it again")
    check_out(s.out)
    if s.backend == "mjx":
        from eaco_jax.gait.walk_route_mjx import check_impl

        check_impl(s.impl)  # before planning
    built = build(s)
    scene = built.problem.scene
    from eaco_jax.problems.scenes import load_scene

    original = load_scene(s.scene)
    table = planning_speeds(s.speeds, s.gaits)
    route, planned, plan_info = plan(s, built)
    spec = load_robot("nao")
    gaits = wr.load_walk_gaits(s.gaits)
    ctrl = s.controller(gaits)
    max_time = s.walk_seconds(planned)
    heading = wr.start_heading(original, route)
    model = sw.scene_model(original, spec, start_heading=heading)
    t0 = time.perf_counter()
    walks: list[dict[str, Any]] = []
    if s.backend == "mjx":
        nominal, walks = _walk_mjx(s, original, route, spec, gaits, ctrl, model, heading,
                                   max_time, planned)
    else:
        nominal = wr.walk(original, route, spec, gaits, ctrl, max_time=max_time, model=model,
                          motors=s.motors)
    if s.worlds and s.backend == "native":
        steps = int(math.ceil(max_time / spec.control_dt))
        push_steps = int(math.ceil(planned / spec.control_dt))
        inputs, _ = wr.sample_walk_worlds(model, spec, int(s.worlds), steps, push_steps,
                                          seed=int(s.seed), stream=s.stream)
        for i, world in enumerate(inputs):
            w = wr.walk(original, route, spec, gaits, ctrl, max_time=max_time, model=model,
                        world=world, record_every=10, motors=s.motors)
            w["world"] = i
            walks.append(w)
    seconds = time.perf_counter() - t0
    record: dict[str, Any] = {
        "scene": original.name,
        "scene_source": s.scene,
        "robot": spec.name,
        "backend": s.backend if s.backend == "native" else f"mjx-{s.impl}",
        "motors": s.motors,
        "planning": {**plan_info, "clearance_m": scene.clearance, "ramps": s.ramps,
                     "speeds": s.speeds,
                     "speed_mps": float(table.speed(0.0)),
                     "yaw_rate_deg_s": float(table.yaw_rate_deg_s),
                     "planned_time_s": planned,
                     "planned_length_m": float(np.sum(np.linalg.norm(np.diff(route, axis=0),
                                                                     axis=1)))},
        "route": route.tolist(),
        "controller": dataclasses.asdict(ctrl),
        "gaits": s.gaits,
        "max_time_s": max_time,
        "nominal": nominal,
        "settings": {f.name: getattr(s, f.name) for f in dataclasses.fields(s)},
        "seconds": seconds,
        "device": (f"CPU ({jax.devices('cpu')[0].platform}), native MuJoCo, one thread"
                   if s.backend == "native" else
                   f"{jax.devices()[0].device_kind} ({jax.devices()[0].platform}), MJX "
                   f"impl={s.impl}, {1 + int(s.worlds)} worlds in one call"),
    }
    if s.worlds:
        record["worlds"] = {"stream": s.stream, "seed": int(s.seed),
                            **_success_stats(walks, planned), "walks": walks}
    if s.out is not None:
        from eaco_jax.outputs import write_json

        folder = Path(s.out)
        record["out"] = str(folder)
        write_json(folder / "walk.json", record)
        draw(original, record, folder / "walk.png")
    return record


def _walk_mjx(s: WalkSettings, scene: Any, route: np.ndarray, spec: Any, gaits: Any,
              ctrl: Any, model: Any, heading: float, max_time: float,
              planned: float) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The nominal walk and one per randomised world, all in one batched MJX call (the
    worlds those of the native backend for the same ``--worlds``, ``--seed``, ``--stream``)."""
    from eaco_jax.gait import walk_route_mjx as wm

    if s.worlds:
        push_steps = int(math.ceil(planned / spec.control_dt))
        batch, _ = wm.world_batch(model, spec, int(s.worlds), push_steps, route[0], heading,
                                  seed=int(s.seed), stream=s.stream)
        batch = wm.with_nominal(batch, model, spec, route[0], heading)
    else:
        batch = wm.nominal_batch(model, spec, route[0], heading)
    out = wm.walk_batch(scene, route, spec, gaits, ctrl, batch, max_time=max_time,
                        model=model, impl=s.impl, motors=s.motors)
    recs = wm.records(out, route)
    nominal = recs[0]
    walks = []
    for i, w in enumerate(recs[1:]):
        w["trajectory"] = _every(w["trajectory"], 2)  # 0.2 s, as the native worlds' 10 steps
        w["world"] = i
        walks.append(w)
    return nominal, walks


def _every(rows: list[list[float]], k: int) -> list[list[float]]:
    """Every ``k``-th trajectory row, the last one kept."""
    out = rows[k - 1 :: k]
    if rows and (not out or out[-1] is not rows[-1]):
        out.append(rows[-1])
    return out


def draw(scene: Any, record: dict[str, Any], path: str | Path | None = None) -> Any:
    """Top view: obstacles, ramps, the planned route and the walked trajectories (nominal
    bold; randomised worlds thin, red where the walk failed)."""
    from matplotlib.patches import Polygon

    from eaco_jax import plots

    fig, ax = plots.subplots(figsize=(6.0, 6.0))
    for r in scene.ramps:
        ax.add_patch(Polygon(np.asarray(r.polygon), closed=True, facecolor="tan", alpha=0.5,
                             hatch="//", edgecolor="0.4"))
    for o in scene.obstacles:
        ax.add_patch(Polygon(np.asarray(o.polygon), closed=True, color="0.55", alpha=0.8))
    for w in (record.get("worlds") or {}).get("walks", []):
        xy = np.asarray(w["trajectory"])[:, 1:3]
        ax.plot(xy[:, 0], xy[:, 1], "-", lw=0.6, alpha=0.5,
                color="tab:orange" if w["success"] else "tab:red")
    route = np.asarray(record["route"])
    ax.plot(route[:, 0], route[:, 1], "--o", color="tab:green", ms=3, lw=1.2,
            label=f"planned ({record['planning']['planned_time_s']:.1f} s)")
    nom = record["nominal"]
    xy = np.asarray(nom["trajectory"])[:, 1:3]
    ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:blue", lw=1.8,
            label=f"walked, nominal ({nom['walked_time_s']:.1f} s, "
                  f"{'success' if nom['success'] else 'failed'})")
    if nom["fell"] or nom["contact"]:
        ax.plot(*xy[-1], "x", color="tab:red", ms=10)
    ax.plot(*route[0], "s", color="k", ms=8, label="start")
    ax.plot(*route[-1], "*", color="tab:red", ms=12, label="goal")
    title = f"{record['scene']}: walk the planned route"
    if "worlds" in record:
        wd = record["worlds"]
        title += f" ({wd['successes']}/{wd['n']} worlds succeed"
        title += ", MJX)" if record.get("backend", "native") != "native" else ")"
    ax.set_title(title, fontsize=10)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.legend(loc="lower right", fontsize=7)
    return plots.save_figure(fig, path) if path is not None else fig


def summary(record: dict[str, Any]) -> str:
    nom = record["nominal"]
    p = record["planning"]
    text = (f"{record['scene']}: planned {p['planned_time_s']:.1f} s over "
            f"{p['planned_length_m']:.2f} m ({p['planner']}); nominal walk "
            f"{'succeeded' if nom['success'] else 'failed'} in {nom['walked_time_s']:.1f} s "
            f"(closest approach {nom['closest_approach_m']:.3f} m"
            f"{', fell' if nom['fell'] else ''}{', contact' if nom['contact'] else ''})")
    if "worlds" in record:
        w = record["worlds"]
        lo, hi = w["success_rate_ci95"]
        text += (f"; {w['successes']}/{w['n']} randomised worlds succeed (95% CI "
                 f"{100 * lo:.0f}-{100 * hi:.0f}%)")
    return text


KIND = RunKind("walk", WalkSettings, build, run, None, summary, resumable=False)
