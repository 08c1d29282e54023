"""Join gait-library runs of one arm each into the seed-paired comparison (issue #32).

    python experiments/library_merge.py RUN_A/gait_library.json RUN_B/gait_library.json \
        --out experiments/results/gait_library/constrained_warp_track_turn/compare.json

``gait_library.py --gait-arms eaco`` and ``--gait-arms qdax`` in two processes (on a GPU, one
call each fits a call's time limit where both together do not) give the same comparison as one
run of both arms: the same seeds, problem, grid, evaluations and test worlds, which this checks
before joining. Writes the per-arm summaries, the seed-paired Wilcoxon p-values (as
``gait_library.py`` does) and, per metric, the mean paired difference eaco - other with a
bootstrap 95 % interval over the seeds.
"""

from __future__ import annotations

import argparse
import json
import sys
from datetime import date
from pathlib import Path

import numpy as np
from gait_library import compare

from eaco_jax.outputs import write_json

SAME = ("problem", "backend", "horizon_s", "constrained", "steering", "target_noise", "free",
        "worlds", "test_worlds", "grid", "speed_range", "yaw_range", "ants", "iterations")
METRICS = ("coverage", "qd_score", "max_fitness", "test_fall_rate_mean", "test_cells_never_fell",
           "test_cells_feasible")


def paired_difference(a: list[float], b: list[float], seed: int = 0) -> dict:
    """Mean of ``a - b`` over the seeds with a bootstrap 95 % interval (10,000 resamples)."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    boots = np.random.default_rng(seed).choice(d, (10_000, len(d))).mean(1)
    return {"mean": float(d.mean()), "ci_low": float(np.percentile(boots, 2.5)),
            "ci_high": float(np.percentile(boots, 97.5)), "a_larger": int(np.sum(d > 0)),
            "n": len(d)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    gaits = [json.loads(p.read_text())["gait"] for p in args.runs]
    for key in SAME:
        if any(g[key] != gaits[0][key] for g in gaits[1:]):
            raise SystemExit(f"the runs differ in {key}: {[g[key] for g in gaits]}")
    rows: dict[str, list[dict]] = {}
    for g in gaits:
        for arm, rs in g["rows"].items():
            if arm in rows:
                raise SystemExit(f"arm {arm} is in more than one run")
            rows[arm] = rs
    seeds = [r["seed"] for r in next(iter(rows.values()))]
    if any([r["seed"] for r in rs] != seeds for rs in rows.values()):
        raise SystemExit("the runs' seeds differ")
    metrics = [m for m in METRICS if all(m in r for rs in rows.values() for r in rs)]
    cmp = compare(rows, tuple(metrics))
    if "eaco" in rows:
        for arm in rows:
            if arm != "eaco":
                cmp[f"eaco_minus_{arm}"] = {
                    m: paired_difference([r[m] for r in rows["eaco"]], [r[m] for r in rows[arm]])
                    for m in metrics}
    write_json(args.out, {
        "command": "python experiments/library_merge.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "runs": [str(p) for p in args.runs], "seeds": seeds,
        "settings": {k: gaits[0][k] for k in SAME}, "seconds": {
            arm: g["seconds"] for g in gaits for arm in g["rows"]},
        "summary": cmp})
    for arm in rows:
        print(arm, {m: round(cmp[arm][m]["mean"], 4) for m in metrics})
    for k, v in cmp.items():
        if k.startswith("eaco_"):
            print(k, {m: (round(x["mean"], 4) if isinstance(x, dict) else round(x, 4))
                      for m, x in v.items()})


if __name__ == "__main__":
    main()
