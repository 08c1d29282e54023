"""Do the fast solver settings keep a gait's fitness close to a high-accuracy simulation?

Each gait is simulated on the native backend twice: with the robot spec's ``fast`` settings
(the ones every optimisation uses) and with its ``accurate`` settings (4x smaller timestep,
many more solver iterations). Prints a table and writes JSON.

    python experiments/gait_accuracy.py --gaits experiments/results/nao_best_gait.json \
        --horizon 20 --out experiments/results/gait_accuracy.json

Without ``--gaits`` a few hand-set gaits (standing, slow and medium walks) are used.
Tolerance stated and checked: |fitness_fast - fitness_accurate| <= max(0.1 m, 10 %).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import numpy as np  # noqa: E402

from eaco_jax.gait import walk_engine as we  # noqa: E402
from eaco_jax.problems.gait import make_gait_problem  # noqa: E402

ABS_TOL = 0.1
REL_TOL = 0.10


def hand_set_gaits() -> dict[str, np.ndarray]:
    base = dict(step_length=0.0, hip_height=0.21, duty_ratio=0.6, period=0.45, foot_lift=0.02,
                step_width=0.0, lateral_sway=0.0, torso_pitch=0.0, arm_swing=0.0,
                hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
                turn_rate=0.0)
    gaits = {"stand": dict(base, foot_lift=0.0, hip_height=0.22),
             "walk_s3cm": dict(base, step_length=0.03, period=0.4),
             "walk_s6cm": dict(base, step_length=0.06, period=0.4, hip_height=0.2)}
    return {k: np.array([v[n] for n in we.PARAM_NAMES], np.float32) for k, v in gaits.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gaits", nargs="*", default=[], help="JSON files with a 'vector'")
    ap.add_argument("--horizon", type=float, default=20.0)
    ap.add_argument("--slope", type=float, default=None, help="default: the gait file's slope")
    ap.add_argument("--out", default="experiments/results/gait_accuracy.json")
    args = ap.parse_args()
    gaits: dict[str, tuple[np.ndarray, float]] = {}
    for path in args.gaits:
        raw = json.loads(Path(path).read_text())
        slope = args.slope if args.slope is not None else float(raw.get("slope_deg", 0.0))
        gaits[Path(path).stem] = (np.asarray(raw["vector"], np.float32), slope)
    if not gaits:
        gaits = {k: (v, args.slope or 0.0) for k, v in hand_set_gaits().items()}

    rows = []
    print(f"{'gait':18s} {'slope':>5s} {'fit fast':>9s} {'fit acc':>8s} {'|diff|':>7s} "
          f"{'fell f/a':>9s} {'t fast':>7s} {'t acc':>7s} {'ok':>3s}")
    for name, (vec, slope) in gaits.items():
        res = {}
        for acc in ("fast", "accurate"):
            p = make_gait_problem("nao", backend="native", horizon=args.horizon, slope_deg=slope,
                                  accuracy=acc)
            t0 = time.time()
            res[acc] = p.simulate(vec, record=False)
            res[acc]["seconds"] = time.time() - t0
            res[acc]["timestep"] = p.spec.solver(acc)["timestep"]
            res[acc]["iterations"] = p.spec.solver(acc)["iterations"]
        f, a = res["fast"]["fitness"], res["accurate"]["fitness"]
        diff = abs(f - a)
        ok = diff <= max(ABS_TOL, REL_TOL * abs(a))
        rows.append({"gait": name, "slope_deg": slope, "horizon": args.horizon,
                     "fast": res["fast"], "accurate": res["accurate"], "abs_diff": diff,
                     "within_tolerance": bool(ok)})
        print(f"{name:18s} {slope:5.1f} {f:9.3f} {a:8.3f} {diff:7.3f} "
              f"{res['fast']['fell']!s:>4s}/{res['accurate']['fell']!s:<4s} "
              f"{res['fast']['seconds']:7.1f} {res['accurate']['seconds']:7.1f} "
              f"{'yes' if ok else 'NO':>3s}", flush=True)
    out = {"tolerance": {"abs_m": ABS_TOL, "rel": REL_TOL}, "rows": rows}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
