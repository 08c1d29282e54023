"""Walk EACO's planned routes with the NAO on native MuJoCo (issue #32, item 4).

    python experiments/walk_route.py --worlds 12              # default + random scenes 1000..
    python experiments/walk_route.py --scenes default --worlds 2   # a smoke test

Scenes: the shipped default and ``random_scene(SEED)`` for SEED from 1000 on (route planning's
selection scenes are 0-24 and its report scenes 100-124; none of these is chosen on anything
here), skipping a scene the walking robot's plan refuses (the goal walled in once obstacles are
grown by the 0.4 m walking clearance and ramps are obstacles). Routes: the path colony, plan
seed 0, 150 iterations. Worlds: the test stream of run seed 0 (nothing is chosen on them),
batch 0, the same worlds for every scene. One JSON per scene under experiments/results/walk/
plus summary.json (device, versions, command, date).
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import date
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import device_info  # noqa: E402

from eaco_jax.errors import ProblemError  # noqa: E402
from eaco_jax.outputs import write_json  # noqa: E402
from eaco_jax.runs import get  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default="default,random:1000,random:1001,random:1002,"
                    "random:1004")
    ap.add_argument("--worlds", type=int, default=12)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "walk")
    args = ap.parse_args()
    kind = get("walk")
    rows = []
    t0 = time.perf_counter()
    for name in args.scenes.split(","):
        folder = args.out / name.replace(":", "_")
        settings = kind.make_settings({"scene": name, "worlds": args.worlds,
                                       "out": str(folder)})
        try:
            rec = kind.run(settings)
        except ProblemError as err:
            print(f"{name}: skipped ({err})", flush=True)
            rows.append({"scene": name, "skipped": str(err)})
            continue
        print(kind.summary(rec), flush=True)
        w = rec["worlds"]
        rows.append({"scene": name, "planned_time_s": rec["planning"]["planned_time_s"],
                     "plan_gap_percent": rec["planning"].get("gap_percent"),
                     "nominal_success": rec["nominal"]["success"],
                     "nominal_walked_time_s": rec["nominal"]["walked_time_s"],
                     "nominal_closest_approach_m": rec["nominal"]["closest_approach_m"],
                     **{k: v for k, v in w.items() if k != "walks"},
                     "closest_approach_m_successes": [x["closest_approach_m"]
                                                      for x in w["walks"] if x["success"]],
                     "file": str((folder / "walk.json").relative_to(HERE.parent))})
    done = [r for r in rows if "skipped" not in r]
    total = {"n": sum(r["n"] for r in done), "successes": sum(r["successes"] for r in done),
             "falls": sum(r["falls"] for r in done), "contacts": sum(r["contacts"] for r in done),
             "nominal_successes": sum(r["nominal_success"] for r in done),
             "scenes": len(done)}
    from eaco_jax.gait.stats import falls_interval

    total["success_rate"] = total["successes"] / max(total["n"], 1)
    total["success_rate_ci95"] = list(falls_interval(total["successes"], total["n"]))
    write_json(args.out / "summary.json", {
        "command": "python experiments/walk_route.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "device": device_info(), "seconds": time.perf_counter() - t0,
        "seeds": {"plan": "path colony seed 0", "worlds": "test stream of run seed 0, batch 0",
                  "scenes": "default + random_scene(1000..) (planning used 0-24 and 100-124)"},
        "total": total, "scenes": rows})
    print(total)


if __name__ == "__main__":
    main()
