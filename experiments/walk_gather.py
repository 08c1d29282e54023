"""Gather per-scene route-walk runs (``walk_route.py --scenes S --out DIR/S``, e.g. one process per
scene on a GPU) into one summary, and keep their records small.

    python experiments/walk_gather.py RUN_DIR --out experiments/results/walk_mjx

``RUN_DIR/<scene>/summary.json`` and ``RUN_DIR/<scene>/<scene>/walk.json`` are read; the output
holds ``summary.json`` (every scene's row, the totals, each run's command, device and seconds)
and per scene ``walk.json`` and ``walk.png``. A walk's trajectory is kept for the nominal walk
and for every walk that did not succeed; the successful worlds' trajectories are dropped
(they are drawn in ``walk.png``), which keeps a 100-world record near 100 kB.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from datetime import date
from pathlib import Path

from eaco_jax.gait.stats import falls_interval
from eaco_jax.outputs import write_json


def totals(rows: list[dict]) -> dict:
    """Success, falls, contacts and times over every scene's worlds."""
    ratios = [x for r in rows for x in r["walked_over_planned_success"]]
    n, ok = sum(r["n"] for r in rows), sum(r["successes"] for r in rows)
    return {"n": n, "successes": ok,
            "falls": sum(r["falls"] for r in rows),
            "contacts": sum(r["contacts"] for r in rows),
            "nominal_successes": sum(bool(r["nominal_success"]) for r in rows),
            "scenes": len(rows),
            "scenes_at_least_95_percent": sum(r["successes"] >= 0.95 * r["n"] for r in rows),
            "worst_scene_success_rate": min(r["successes"] / r["n"] for r in rows),
            "walked_over_planned_max": max(ratios, default=None),
            "walked_over_planned_min": min(ratios, default=None),
            "within_20_percent": sum(abs(x - 1) <= 0.2 for x in ratios),
            "closest_approach_m_min_success": min(
                (r["closest_approach_m_min_success"] for r in rows
                 if r["closest_approach_m_min_success"] is not None), default=None),
            "success_rate": ok / max(n, 1),
            "success_rate_ci95": list(falls_interval(ok, n))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    runs = sorted(args.run_dir.glob("*/summary.json"))
    if not runs:
        sys.exit(f"no */summary.json under {args.run_dir}")
    rows, sources = [], []
    for path in runs:
        summary = json.loads(path.read_text())
        for row in summary["scenes"]:
            if "skipped" in row:
                continue
            folder = row["scene"].replace(":", "_")
            rec = json.loads((path.parent / folder / "walk.json").read_text())
            for w in rec["worlds"]["walks"]:
                if w["success"]:
                    w.pop("trajectory", None)
            rec["trajectories_kept"] = "the nominal walk and every walk that did not succeed"
            target = args.out / folder
            write_json(target / "walk.json", rec)
            shutil.copy(path.parent / folder / "walk.png", target / "walk.png")
            rows.append({**row, "file": str(target / "walk.json")})
        sources.append({k: summary[k] for k in ("command", "date", "device", "seconds",
                                               "backend", "seeds")})
    order = {"default": 0}
    rows.sort(key=lambda r: (order.get(r["scene"], 1), r["scene"]))
    write_json(args.out / "summary.json", {
        "command": "python experiments/walk_gather.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "runs": sources, "backend": sources[0]["backend"],
        "device": sources[0]["device"], "seeds": sources[0]["seeds"],
        "total": totals(rows), "scenes": rows})
    print(json.dumps(totals(rows)))


if __name__ == "__main__":
    main()
