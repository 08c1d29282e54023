"""Large-TSP settings compared at equal iterations (issue 33): the quality each reaches per
iteration, apart from the machine's speed.

The targets of issue 33 are on a GPU clock, and a CPU cannot time them. What a CPU can measure
is how far each setting gets in the same number of iterations with the same number of ants
(equal evaluations): a setting that is better per iteration and costs about the same per
iteration is the one to time on the GPU next. Each (arm, run seed) is one fresh ``python -m
eaco_jax tsp FILE --iterations N --seed SEED ARGS`` process on a random uniform instance of
``tsp_large.py`` (``--size``, ``--instance-seed``: use a selection instance, never a report
one). Each row: the best length after the run and at ``--marks`` iterations (from the
record's ``history_best``), over the BHH estimate of a random uniform optimum, seconds per
iteration on this machine (a guide only: a GPU ranks the settings' costs differently).

    python experiments/tsp_equal_iterations.py --size 10000 --instance-seed 1 \\
        --iterations 1000 --seeds 0 1 --arm moves32="--construction moves" \\
        --arm or3opt32="--construction moves-or3opt" \\
        --common="--max-new-edges 32 --ls-focus-width 128 --ants 96"
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import shlex
import sys
from pathlib import Path

from common import eaco_tsp, t_ci, write_results
from tsp_large import BHH, SIDE, random_instance

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_large" / "equal_iterations.json"


def run_arm(path: Path, iterations: int, seed: int, args: list[str]) -> dict:
    """One fresh ``eaco tsp`` process of ``iterations`` iterations: its record (no tour)."""
    done = eaco_tsp([path, "--iterations", iterations, "--seed", seed, *args])
    if done["error"]:
        return {"seed": seed, "error": done["error"], "argv": done["argv"]}
    return {**done["record"], "wall_seconds": done["wall_seconds"], "argv": done["argv"]}


def summarize(rows: list[dict], labels: list[str], marks: list[int]) -> dict:
    """Per arm: runs, mean and t interval over BHH at the end and the mean at each mark,
    mean seconds per iteration."""
    summary = {}
    for label in labels:
        ok = [r for r in rows if r["arm"] == label and "error" not in r]
        if not ok:
            continue
        vals = [r["over_bhh_percent"] for r in ok]
        summary[label] = {
            "n": len(vals), "over_bhh_mean": sum(vals) / len(vals),
            "over_bhh_ci95_t": t_ci(vals) if len(vals) > 1 else None,
            "over_bhh_at_mean": {str(m): sum(r["over_bhh_at"][str(m)] for r in ok) / len(ok)
                                 for m in marks if all(str(m) in r["over_bhh_at"] for r in ok)},
            "seconds_per_iteration_mean": sum(r["seconds_per_iteration"] for r in ok) / len(ok)}
    return summary


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=10000)
    ap.add_argument("--instance-seed", type=int, default=1,
                    help="the random instance (1: the selection instance of tsp_large)")
    ap.add_argument("--iterations", type=int, default=1000)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--arm", action="append", required=True,
                    help="LABEL=\"eaco tsp flags\" (repeat)")
    ap.add_argument("--common", default="", help="flags for every arm")
    ap.add_argument("--marks", type=int, nargs="*", default=[100, 250, 500])
    ap.add_argument("--work", type=Path, default=Path("/tmp/tsp_equal_iterations"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    arms = []
    for spec in a.arm:
        label, sep, flags = spec.partition("=")
        if not sep or not label:
            ap.error(f"--arm takes LABEL=\"flags\", got {spec!r}")
        arms.append((label, shlex.split(a.common) + shlex.split(flags)))
    a.work.mkdir(parents=True, exist_ok=True)
    path = random_instance(a.work, a.size, a.instance_seed)
    bhh = BHH * math.sqrt(a.size * SIDE**2)
    rows = []
    for seed in a.seeds:  # seeds outside, arms inside: a slow machine drifts alike for all
        for label, flags in arms:
            row = run_arm(path, a.iterations, seed, flags)
            row["arm"] = label
            if "error" not in row:
                hist = row.pop("history_best", [])
                row["over_bhh_percent"] = 100.0 * (row["best_length"] / bhh - 1.0)
                row["over_bhh_at"] = {str(m): 100.0 * (hist[m - 1] / bhh - 1.0)
                                      for m in a.marks if m <= len(hist)}
            rows.append(row)
            print(json.dumps({k: row.get(k) for k in ("arm", "seed", "best_length",
                                                       "over_bhh_percent",
                                                       "seconds_per_iteration", "error")}),
                  flush=True)
    summary = summarize(rows, [label for label, _ in arms], a.marks)
    print(f"{'arm':<14} {'n':>2} {'over BHH %':>10} {'s/iteration':>11}")
    for label, s in summary.items():
        print(f"{label:<14} {s['n']:>2} {s['over_bhh_mean']:>10.3f} "
              f"{s['seconds_per_iteration_mean']:>11.4f}")
    command = " ".join([Path(sys.argv[0]).name, *map(shlex.quote, argv if argv is not None
                                                      else sys.argv[1:])])
    write_results(a.out, rows, date=datetime.date.today().isoformat(), command=command,
                  seeds={"instance": a.instance_seed, "run": a.seeds,
                         "role": "selection instance: chooses, reports nothing"},
                  summary=summary, bhh_estimate=bhh, iterations=a.iterations)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
