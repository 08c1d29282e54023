"""ACOTSP beside our colony: best tour length reached in a fixed time, without local search.

Runs an ACOTSP binary (López-Ibáñez & Stützle's C implementation, built outside this
repository; nothing of it is committed) with MMAS, 40 ants, no local search, one try of
``--seconds`` per seed, one seed at a time (pin with ``taskset -c N``), and writes the lengths
and gaps as JSON next to ``tsp_quality.py``'s no-LS table, for the same-wall-time comparison
of issue 2.

    taskset -c 1 python experiments/acotsp_quality.py ~/ACOTSP/acotsp --instances kroA100
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results" / "acotsp_quality.json"


def tsp_file(name: str) -> Path:
    """The bundled .tsp file of an instance (what ACOTSP reads)."""
    from eaco_jax.problems.tsp import DATA_DIR

    return DATA_DIR / f"{name}.tsp"


def run_acotsp(binary: Path, tsp_file: Path, seconds: float, seed: int) -> dict:
    """One ACOTSP try: best length, the iteration and time it was found at, iterations run."""
    out = subprocess.run(
        [str(binary), "-i", str(tsp_file), "--mmas", "-m", "40", "-l", "0", "-r", "1",
         "-t", str(seconds), "--seed", str(seed), "--quiet"],
        capture_output=True, text=True, check=True).stdout
    best = re.findall(r"Best (\d+), found at iteration (\d+), found at time ([\d.]+)", out)
    iters = [int(x) for x in re.findall(r"iteration (\d+), b-fac", out)]
    if not best:
        raise RuntimeError(f"no result in ACOTSP's output:\n{out[-500:]}")
    length, at_iter, at_time = best[-1]
    return {"seed": seed, "length": int(length), "found_at_iteration": int(at_iter),
            "found_at_seconds": float(at_time), "iterations": max(iters, default=None)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("binary", type=Path, help="the acotsp executable")
    ap.add_argument("--instances", nargs="+", default=["eil51", "kroA100"])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    from eaco_jax.problems.tsp import load_tsplib

    rows = []
    for name in args.instances:
        optimum = load_tsplib(name).optimum
        runs = [run_acotsp(args.binary, tsp_file(name), args.seconds, s)
                for s in range(1, args.seeds + 1)]
        gaps = [100.0 * (r["length"] / optimum - 1.0) for r in runs]
        rows.append({"instance": name, "optimum": optimum, "seconds": args.seconds,
                     "seeds": args.seeds, "lengths": [r["length"] for r in runs],
                     "gaps_percent": gaps, "mean_gap_percent": sum(gaps) / len(gaps),
                     "optimum_hits": sum(r["length"] == optimum for r in runs), "runs": runs})
        print(f"{name:>8} ACOTSP MMAS {args.seconds:.0f} s x {args.seeds} seeds: mean gap "
              f"{rows[-1]['mean_gap_percent']:.3f}%  optimum {rows[-1]['optimum_hits']}/"
              f"{args.seeds}  lengths {rows[-1]['lengths']}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"binary": "ACOTSP (MMAS, 40 ants, -l 0)", "rows": rows},
                                   indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
