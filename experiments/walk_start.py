"""Falls in a route walk's first seconds, by gait library and start ramp (issue #32).

    python experiments/walk_start.py --worlds 32 --seconds 8 --ramps 0,3,6 \
        --gaits nao_library,nao_constrained

Most falls of ``nao_library`` on the test scenes came in the first five seconds, while the
walk starts with its fastest cell. This walks only the start of each tuning scene's route
(``random_scene(2004..2009)``, planned as ``walk_tune.py`` plans them) in selection-stream
worlds of run seed 0 (the report's worlds are the test stream), for each gait library and each
``Controller.start_ramp_s``, and counts the falls and the distance covered. Writes --out
(device, versions, command, date).
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
from common import device_info
from walk_tune import tuning_walks

from eaco_jax.outputs import write_json

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", default=",".join(f"random:{s}" for s in range(2004, 2010)))
    ap.add_argument("--worlds", type=int, default=32)
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--ramps", default="0,3,6", help="comma-separated start_ramp_s values")
    ap.add_argument("--gaits", default="nao_library,nao_constrained")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "walk" / "start_ramp.json")
    args = ap.parse_args()
    from eaco_jax.gait import walk_route as wr
    from eaco_jax.gait.robot import load_robot
    from eaco_jax.runs import walk as rw

    spec = load_robot("nao")
    t0 = time.perf_counter()
    setups = []
    for name in args.scenes.split(","):
        s = rw.WalkSettings(scene=name)
        scene, route, _, model, _, inputs = tuning_walks(s, rw.build(s), spec, args.worlds,
                                                         "selection")
        setups.append((name, scene, route, model, inputs))
    rows = []
    for lib in args.gaits.split(","):
        gaits = wr.load_walk_gaits(lib)
        for ramp in (float(r) for r in args.ramps.split(",")):
            ctrl = wr.Controller(start_ramp_s=ramp)
            falls, dist = [], []
            for name, scene, route, model, inputs in setups:
                for i, world in enumerate(inputs):
                    w = wr.walk(scene, route, spec, gaits, ctrl, max_time=args.seconds,
                                model=model, world=world, record_every=50, motors="spec")
                    falls.append({"scene": name, "world": i, "fell": w["fell"],
                                  "fall_time_s": w["fall_time_s"]})
                    dist.append(float(np.linalg.norm(np.asarray(w["trajectory"][-1][1:3])
                                                     - route[0])))
            n_fell = sum(f["fell"] for f in falls)
            row = {"gaits": lib, "start_ramp_s": ramp, "n": len(falls), "falls": n_fell,
                   "distance_m_mean": float(np.mean(dist)), "walks": falls}
            rows.append(row)
            print(f"{lib} start_ramp_s {ramp:g}: {n_fell}/{len(falls)} fell in the first "
                  f"{args.seconds:g} s, mean distance {row['distance_m_mean']:.2f} m", flush=True)
    write_json(args.out, {
        "command": "python experiments/walk_start.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "device": device_info(), "seconds": time.perf_counter() - t0,
        "seeds": {"plan": "path colony seed 0", "worlds": "selection stream of run seed 0, "
                  "batch 0", "scenes": "random_scene(2004..2009): tuning only"},
        "walk_seconds": args.seconds, "motors": "spec", "rows": rows})


if __name__ == "__main__":
    main()
