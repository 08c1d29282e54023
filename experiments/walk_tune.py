"""Choose the walk controller's settings on tuning scenes and selection-stream worlds (issue #32).

    python experiments/walk_tune.py --worlds 8 --configs '[{}, {"max_steer": 0.4}]'

Scenes: ``random_scene(2000..)`` (none of them is a scene the walk is reported on: those are
``default`` and ``random_scene(1000..)``, experiments/walk_route.py), skipping one the walking
plan refuses. Worlds: the *selection* stream of run seed 0 (the report uses the test stream).
``--speeds nao`` plans with the path planner's gait table (the first tuning
round: the gait library's planning entry is fitted from it), ``walk`` with the library's
planning entry (the check that the fitted model holds). Each config is a set of
:class:`~eaco_jax.gait.walk_route.Controller` fields over the defaults (and over the
controller settings the library chose for itself, its file's ``controller``, as ``eaco walk``
takes them); every config walks
the same routes in the same worlds, with each gait library of ``--gaits`` (routes planned once,
with the shipped library's planning entry). Writes --out (device, versions, command, date): per
config the successes, falls, contacts, walked / planned time over all walks and the time
model fitted to them (:func:`time_model`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
from common import device_info

from eaco_jax.errors import ProblemError
from eaco_jax.outputs import write_json

HERE = Path(__file__).resolve().parent


def time_model(walks: list[dict], routes: dict[str, dict[str, float]]) -> dict | None:
    """Least-squares fit of the successful walks' times to the planner's model, ``length /
    speed + sum |heading change| / yaw_rate``: the speed and yaw rate a planner should price
    for this controller (None with fewer than two distinct routes)."""
    ok = [w for w in walks if w["success"]]
    if len({w["scene"] for w in ok}) < 2:
        return None
    a = np.array([[routes[w["scene"]]["length_m"], routes[w["scene"]]["turn_rad"]] for w in ok])
    t = np.array([w["walked_time_s"] for w in ok])
    (inv_v, inv_w), *_ = np.linalg.lstsq(a, t, rcond=None)
    pred = a @ np.array([inv_v, inv_w])
    return {"speed_mps": float(1 / inv_v) if inv_v > 0 else None,
            "yaw_rate_deg_s": float(math.degrees(1 / inv_w)) if inv_w > 0 else None,
            "walks": len(ok), "rms_residual_s": float(np.sqrt(np.mean((t - pred) ** 2)))}


def tuning_walks(settings, built, spec, worlds: int, stream: str) -> tuple:
    """One tuning scene's walks: ``(scene, route, planned time, model, max_time, worlds'
    inputs)``, the route planned by ``settings`` (a ``WalkSettings``) from its ``built``
    problem and ``worlds`` worlds of ``stream`` of run seed 0, drawn as ``eaco walk`` draws
    them for that route."""
    from eaco_jax.gait import scene_world as sw
    from eaco_jax.gait import walk_route as wr
    from eaco_jax.problems.scenes import load_scene
    from eaco_jax.runs import walk as rw

    route, planned, _ = rw.plan(settings, built)
    scene = load_scene(settings.scene)
    model = sw.scene_model(scene, spec, start_heading=wr.start_heading(scene, route))
    max_time = settings.walk_seconds(planned)
    inputs, _ = wr.sample_walk_worlds(model, spec, worlds,
                                      int(math.ceil(max_time / spec.control_dt)),
                                      int(math.ceil(planned / spec.control_dt)),
                                      seed=0, stream=stream)
    return scene, route, planned, model, max_time, inputs


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default="random:2004,random:2005,random:2006,random:2007")
    ap.add_argument("--worlds", type=int, default=8)
    ap.add_argument("--configs", default="[{}]", help="JSON list of Controller field sets")
    ap.add_argument("--motors", default="servo", choices=("servo", "spec"),
                    help="motor model of the walks (walk_route.MOTORS)")
    ap.add_argument("--speeds", default="walk", help="what the planner prices (eaco walk "
                    "--speeds): 'walk' or a gait speed table such as 'nao'")
    ap.add_argument("--gaits", default="nao", help="comma-separated gait libraries (a shipped "
                    "name or a JSON file, as eaco walk --gaits): every config walks with each")
    ap.add_argument("--plan", default="{}", help="JSON object of further planning settings "
                    "(eaco walk's WalkSettings fields, e.g. clearance or a gait library whose "
                    "planning entry the route prices): every config walks these routes")
    ap.add_argument("--stream", default="selection", choices=("selection", "optimisation"))
    ap.add_argument("--out", type=Path, default=HERE / "results" / "walk" / "tuning.json")
    args = ap.parse_args()
    from eaco_jax.gait import walk_route as wr
    from eaco_jax.gait.robot import load_robot
    from eaco_jax.runs import walk as rw

    spec = load_robot("nao")
    libraries = [(g, wr.load_walk_gaits(g)) for g in args.gaits.split(",")]
    configs = json.loads(args.configs)
    plan_settings = json.loads(args.plan)
    if not isinstance(plan_settings, dict):
        raise SystemExit(f"--plan must be a JSON object of WalkSettings fields, got {args.plan}")
    t0 = time.perf_counter()
    setups = []
    routes: dict[str, dict[str, float]] = {}
    for name in args.scenes.split(","):
        s = rw.WalkSettings(scene=name, speeds=args.speeds, **plan_settings)
        try:
            built = rw.build(s)
        except ProblemError as err:
            print(f"{name}: skipped ({err})", flush=True)
            continue
        scene, route, planned, model, max_time, inputs = tuning_walks(
            s, built, spec, args.worlds, args.stream)
        setups.append((name, scene, route, planned, model, max_time, inputs))
        d = np.diff(route, axis=0)
        heads = np.arctan2(d[:, 1], d[:, 0])
        routes[name] = {"length_m": float(np.linalg.norm(d, axis=1).sum()),
                        "turn_rad": float(np.abs((np.diff(heads) + np.pi) % (2 * np.pi)
                                                 - np.pi).sum()),
                        "planned_time_s": planned}
    rows = []
    for (lib, gaits), cfg in ((lg, c) for lg in libraries for c in configs):
        ctrl = wr.Controller(**{**dict(gaits.controller), **cfg})  # as eaco walk
        walks = []
        for name, scene, route, planned, model, max_time, inputs in setups:
            for i, world in enumerate(inputs):
                w = wr.walk(scene, route, spec, gaits, ctrl, max_time=max_time, model=model,
                            world=world, record_every=50, motors=args.motors)
                walks.append({"scene": name, "world": i, "planned_time_s": planned,
                              **{k: w[k] for k in ("success", "fell", "contact", "reached",
                                                   "walked_time_s", "closest_approach_m",
                                                   "gait_switches", "mode_seconds")}})
        ok = [w for w in walks if w["success"]]
        ratio = [w["walked_time_s"] / w["planned_time_s"] for w in ok]
        row = {"config": cfg, "gaits": lib, "motors": args.motors, "n": len(walks),
               "successes": len(ok),
               "falls": sum(w["fell"] for w in walks),
               "contacts": sum(w["contact"] for w in walks),
               "not_reached": sum(not w["reached"] for w in walks),
               "walked_over_planned_mean": float(np.mean(ratio)) if ratio else None,
               "walked_over_planned_max": float(np.max(ratio)) if ratio else None,
               "closest_approach_m_min_success": (min(w["closest_approach_m"] for w in ok)
                                                  if ok else None),
               "time_model": time_model(walks, routes), "walks": walks}
        rows.append(row)
        print({k: v for k, v in row.items() if k != "walks"}, flush=True)
    write_json(args.out, {
        "command": "python experiments/walk_tune.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "device": device_info(), "seconds": time.perf_counter() - t0,
        "seeds": {"plan": "path colony seed 0", "worlds": f"{args.stream} stream of run seed "
                  "0, batch 0", "scenes": "random_scene(2000..): tuning only"},
        "plan": plan_settings, "scenes": [s[0] for s in setups], "routes": routes,
        "configs": rows})


if __name__ == "__main__":
    main()
