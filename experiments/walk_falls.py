"""When route walks fall: the fall times of every world under a walk results folder (issue #32).

    python experiments/walk_falls.py experiments/results/walk_warp_library --before 5

Reads ``DIR/<scene>/walk.json`` (``walk_route.py`` or ``walk_gather.py`` output) and writes
``DIR/falls.json``: per scene and in total the falls, those before ``--before`` seconds of
walking (the start from standing and its first steps), and the fall times' quartiles.
"""

from __future__ import annotations

import argparse
import json
import sys
from datetime import date
from pathlib import Path

import numpy as np

from eaco_jax.outputs import write_json


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--before", type=float, default=5.0)
    args = ap.parse_args()
    scenes, times = [], []
    for path in sorted(args.folder.glob("*/walk.json")):
        rec = json.loads(path.read_text())
        t = [w["fall_time_s"] for w in rec["worlds"]["walks"] if w["fell"]]
        times += t
        scenes.append({"scene": rec["scene"], "n": len(rec["worlds"]["walks"]), "falls": len(t),
                       "falls_before": sum(x < args.before for x in t)})
    if not scenes:
        sys.exit(f"no */walk.json under {args.folder}")
    q = np.percentile(times, [25, 50, 75]).tolist() if times else None
    total = {"n": sum(s["n"] for s in scenes), "falls": len(times),
             "falls_before": sum(x < args.before for x in times), "fall_time_quartiles_s": q}
    write_json(args.folder / "falls.json", {
        "command": "python experiments/walk_falls.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "before_s": args.before, "total": total, "scenes": scenes})
    print(total)


if __name__ == "__main__":
    main()
