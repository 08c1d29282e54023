"""Walk EACO's planned routes with the NAO on native MuJoCo (issue #32, item 4).

    python experiments/walk_route.py --worlds 20              # default + 10 random scenes
    python experiments/walk_route.py --scenes default --worlds 2   # a smoke test
    python experiments/walk_route.py --backend mjx --impl warp --worlds 100   # MJX, a GPU
    python experiments/walk_route.py --motors spec --worlds 20   # the spec's motor model

Scenes: the shipped default and the first ``--random`` scenes ``random_scene(SEED)`` for SEED
from 1000 on that the walking robot's plan accepts (it refuses a goal walled in once obstacles
are grown by the 0.4 m walking clearance and ramps are obstacles; refused seeds are listed).
Nothing was chosen on these scenes: the controller's settings and the planner's walking model
were chosen on ``random_scene(2004..2009)`` in selection-stream worlds
(experiments/walk_tune.py), route planning's own scenes are 0-24 and 100-124. Routes: the path
colony, plan seed 0, 150 iterations, pricing the gait library's walking model (``eaco walk
--speeds walk``). Worlds: the test stream of run seed 0 (nothing is chosen on them), batch 0,
the same worlds for every scene. One JSON per scene under experiments/results/walk/ plus
summary.json (device, versions, command, date); ``--backend mjx`` walks the nominal and all of a
scene's worlds in one batched MJX call and writes under experiments/results/walk_mjx/ (the
worlds are the native backend's for the same ``--worlds``: ``sample_worlds`` of ``n`` worlds).
``--gaits nao_constrained`` walks the library of the constrained gaits (the stored flat gait);
``--motors spec`` walks with the robot spec's motor model (current limit, back-EMF, gear
efficiency, targets interpolated between control steps, as the gait rollouts simulate it)
instead of the position servos, and writes under experiments/results/walk_spec/ (walk_spec_mjx/
with ``--backend mjx``); nothing is tuned for it.
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import date
from pathlib import Path

from common import device_info
from walk_gather import totals

from eaco_jax.errors import ProblemError
from eaco_jax.outputs import write_json
from eaco_jax.runs import get

HERE = Path(__file__).resolve().parent


def _relative(path: Path) -> str:
    """``path`` relative to the repository where it lies inside it."""
    try:
        return str(path.resolve().relative_to(HERE.parent))
    except ValueError:
        return str(path)


def _done(folder: Path, settings) -> dict | None:
    """The walk record already in ``folder`` if it was run with ``settings``, else None."""
    import dataclasses
    import json

    path = folder / "walk.json"
    if not path.is_file():
        return None
    rec = json.loads(path.read_text())
    return rec if rec.get("settings") == dataclasses.asdict(settings) else None


def compare(out: Path, other: Path, command: str) -> dict:
    """Paired comparison of the walks under ``out`` with those under ``other`` (the same
    scenes and worlds, e.g. ``--motors spec`` against the servos): per scene and in total
    the walks that succeed in both, only here, only there, and the exact two-sided McNemar
    p-value of the discordant pairs; written to ``out``/compare.json."""
    import json
    from math import comb

    def mcnemar(b: int, c: int) -> float:
        n = b + c
        return min(1.0, 2.0 * sum(comb(n, i) for i in range(min(b, c) + 1)) / 2.0**n) if n \
            else 1.0

    rows, tot = [], {"both": 0, "here_only": 0, "there_only": 0, "neither": 0}
    n_worlds = set()
    for path in sorted(out.glob("*/walk.json")):
        here = json.loads(path.read_text())
        there = json.loads((other / path.parent.name / "walk.json").read_text())
        row = {"scene": here["scene_source"], "both": 0, "here_only": 0, "there_only": 0,
               "neither": 0}
        for a, b in zip(here["worlds"]["walks"], there["worlds"]["walks"], strict=True):
            if a["world"] != b["world"]:
                raise ValueError(f"{path}: worlds differ ({a['world']} vs {b['world']})")
            key = ("both" if a["success"] and b["success"] else "here_only" if a["success"]
                   else "there_only" if b["success"] else "neither")
            row[key] += 1
            tot[key] += 1
        n_worlds.add(len(here["worlds"]["walks"]))
        row["mcnemar_p"] = mcnemar(row["here_only"], row["there_only"])
        rows.append(row)
    tot["mcnemar_p"] = mcnemar(tot["here_only"], tot["there_only"])
    rec = {"command": command, "date": str(date.today()), "device": device_info(),
           "here": _relative(out), "there": _relative(other),
           "pairing": "the same scene and world (test stream of run seed 0, worlds 0-"
                      f"{max(n_worlds, default=0) - 1})",
           "total": tot, "scenes": rows}
    write_json(out / "compare.json", rec)
    return rec


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default=None, help="comma-separated scenes (default: "
                    "'default' and --random scenes from random:1000 on)")
    ap.add_argument("--random", type=int, default=10)
    ap.add_argument("--worlds", type=int, default=20)
    ap.add_argument("--backend", default="native", choices=("native", "mjx"))
    ap.add_argument("--impl", default="jax", choices=("jax", "warp"),
                    help="MJX implementation (--backend mjx)")
    ap.add_argument("--motors", default="servo", choices=("servo", "spec"),
                    help="motor model of the walks: position servos, or the robot spec's")
    ap.add_argument("--gaits", default="nao", help="gait library (eaco walk --gaits): a "
                    "shipped name ('nao', 'nao_constrained') or a JSON file; its planning "
                    "entry prices the routes")
    ap.add_argument("--out", type=Path, default=None, help="default: experiments/results/"
                    "walk (walk_spec with --motors spec), + _mjx with --backend mjx")
    ap.add_argument("--skip-done", action="store_true", help="reuse a scene's walk.json "
                    "under --out where it has the same worlds, backend and settings (a run "
                    "cut short continues where it stopped; the summary covers all scenes)")
    ap.add_argument("--compare", type=Path, default=None, help="no walks: pair the walks "
                    "under --out with those under this folder (same scenes and worlds) and "
                    "write --out/compare.json")
    args = ap.parse_args()
    if args.out is None:
        name = "walk" if args.motors == "servo" else "walk_spec"
        args.out = HERE / "results" / (name if args.backend == "native" else f"{name}_mjx")
    if args.compare is not None:
        rec = compare(args.out, args.compare,
                      "python experiments/walk_route.py " + " ".join(sys.argv[1:]))
        print(rec["total"])
        return
    kind = get("walk")
    rows = []
    t0 = time.perf_counter()
    names = args.scenes.split(",") if args.scenes else ["default"]
    seed = 1000
    while not args.scenes and sum(n.startswith("random:") for n in names) < args.random:
        names.append(f"random:{seed}")
        seed += 1
    for name in names:
        folder = args.out / (Path(name).stem if name.endswith(".json")
                             else name.replace(":", "_"))
        settings = kind.make_settings({"scene": name, "worlds": args.worlds,
                                       "out": str(folder), "backend": args.backend,
                                       "impl": args.impl, "motors": args.motors,
                                       "gaits": args.gaits})
        try:
            rec = _done(folder, settings) if args.skip_done else None
            if rec is None:
                rec = kind.run(settings)
        except ProblemError as err:
            print(f"{name}: skipped ({err})", flush=True)
            rows.append({"scene": name, "skipped": str(err)})
            if not args.scenes and name.startswith("random:"):
                names.append(f"random:{seed}")  # keep --random accepted scenes
                seed += 1
            continue
        print(kind.summary(rec), flush=True)
        w = rec["worlds"]
        rows.append({"scene": name, "seconds": rec["seconds"],
                     "planned_time_s": rec["planning"]["planned_time_s"],
                     "plan_gap_percent": rec["planning"].get("gap_percent"),
                     "nominal_success": rec["nominal"]["success"],
                     "nominal_walked_time_s": rec["nominal"]["walked_time_s"],
                     "nominal_closest_approach_m": rec["nominal"]["closest_approach_m"],
                     "planned_length_m": rec["planning"]["planned_length_m"],
                     "walked_over_planned_success": [x["reach_time_s"] / rec["planning"][
                         "planned_time_s"] for x in w["walks"] if x["success"]],
                     **{k: v for k, v in w.items() if k != "walks"},
                     "closest_approach_m_successes": [x["closest_approach_m"]
                                                      for x in w["walks"] if x["success"]],
                     "peak_current_frac_max": max((x.get("peak_current_frac") or 0.0
                                                   for x in w["walks"]), default=None),
                     "file": _relative(folder / "walk.json")})
    done = [r for r in rows if "skipped" not in r]
    total = totals(done)
    write_json(args.out / "summary.json", {
        "command": "python experiments/walk_route.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "device": device_info(), "seconds": time.perf_counter() - t0,
        "backend": "native" if args.backend == "native" else f"mjx-{args.impl}",
        "motors": args.motors,
        "seeds": {"plan": "path colony seed 0", "worlds": "test stream of run seed 0, batch 0",
                  "scenes": "default + random_scene(1000..) (planning used 0-24 and 100-124)",
                  "tuned_on": "controller settings and the walking model: random_scene("
                              "2004..2009), selection stream (experiments/results/walk/"
                              "tuning.json, tuning_check.json); nothing here"},
        "total": total, "scenes": rows})
    print(total)


if __name__ == "__main__":
    main()
