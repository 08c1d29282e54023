"""TSP at 10,000-100,000 cities (issue 33): ``eaco tsp FILE --max-seconds S`` as fresh processes.

Instances: random uniform EUC_2D instances (DyNACO's setting: integer coordinates in
[0, 10^6), one file per ``--instance-seeds`` seed and ``--sizes`` size, written to ``--work``),
and d15112 when a data folder holds it (``common.data_dirs``: ``$EACO_TSPLIB_DIR``,
``shared/data/tsplib`` beside the repository, ...). Each (instance, run seed of ``--seeds``)
is one fresh ``python -m eaco_jax tsp FILE --max-seconds S --seed SEED`` process, its wall
clock taken from the call (start-up and compilation included); ``--seconds`` gives S per size
(one value, or one per size), ``--eaco-args`` extra flags for every run.

Each row: the tour length, the gap where the optimum is known (d15112: TSPLIB's 1,573,084;
random instances: from ``--reference FILE.json``, {"instance name": length}, e.g. LKH-3 runs),
else the length over the Beardwood-Halton-Hammersley estimate 0.7124 sqrt(n A) of a random
uniform optimum (an estimate, not a gap), tours/s, peak host memory (RSS) and device memory
where the backend reports it. Instance seeds (which instances) and run seeds (which colony)
are separate lists; nothing here chooses settings.

    python experiments/tsp_large.py --sizes 10000 --seconds 18 --seeds 0 1 2     # GPU
    python experiments/tsp_large.py --sizes 10000 100000 --seconds 18 172 --seeds 0 1 2 3 4
    python experiments/tsp_large.py --sizes 2000 --seconds 10 --seeds 0 --no-d15112   # smoke
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import data_dirs, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_large.json"
#: the side of the random instances' square, and the BHH constant of a random uniform tour
SIDE, BHH = 1_000_000, 0.7124
D15112_OPTIMUM = 1_573_084


def random_instance(folder: Path, n: int, seed: int) -> Path:
    """A random uniform EUC_2D instance (integer coordinates in [0, SIDE)) as a .tsp file."""
    path = folder / f"rand{n}_s{seed}.tsp"
    if path.is_file():
        return path
    xy = np.random.default_rng([n, seed]).integers(0, SIDE, (n, 2))
    folder.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as fh:
        fh.write(f"NAME : {path.stem}\nTYPE : TSP\nCOMMENT : random uniform, seed {seed}\n"
                 f"DIMENSION : {n}\nEDGE_WEIGHT_TYPE : EUC_2D\nNODE_COORD_SECTION\n")
        np.savetxt(fh, np.column_stack([np.arange(1, n + 1), xy]), fmt="%d")
        fh.write("EOF\n")
    return path


def find_file(name: str) -> Path | None:
    for d in data_dirs():
        if (d / f"{name}.tsp").is_file():
            return d / f"{name}.tsp"
    return None


def run_one(path: Path, seconds: float, seed: int, extra: list[str]) -> dict:
    """One fresh ``eaco tsp`` process: its record (without the tour) and the wall clock."""
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "eaco_jax", "tsp", str(path), "--max-seconds",
                str(seconds), "--seed", str(seed), "--out", tmp, *extra]
        t0 = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if done.returncode:
            return {"instance": path.stem, "seed": seed, "error": done.stderr.strip()[-500:],
                    "wall_seconds": wall}
        rec = json.loads((Path(tmp) / "result.json").read_text())
    rec.pop("tour", None)
    history = rec.pop("history_best", [])
    return {**rec, "wall_seconds": wall, "budget_seconds": seconds,
            "history_points": len(history), "argv": argv[2:]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--seconds", type=float, nargs="+", default=[18.0, 172.0])
    ap.add_argument("--instance-seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--d15112-seconds", type=float, default=75.9)
    ap.add_argument("--no-d15112", action="store_true")
    ap.add_argument("--reference", type=Path, help="JSON {instance: reference length}")
    ap.add_argument("--eaco-args", default="", help="extra flags for every eaco tsp run")
    ap.add_argument("--work", type=Path, default=Path("out/tsp_large"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    seconds = args.seconds if len(args.seconds) == len(args.sizes) else \
        [args.seconds[0]] * len(args.sizes)
    reference = json.loads(args.reference.read_text()) if args.reference else {}
    jobs = [(random_instance(args.work, n, s), sec, n) for n, sec in zip(args.sizes, seconds,
                                                                          strict=True)
            for s in args.instance_seeds]
    d15112 = None if args.no_d15112 else find_file("d15112")
    if d15112 is not None:
        jobs.append((d15112, args.d15112_seconds, 15112))
    elif not args.no_d15112:
        print("d15112: not in any data folder (skipped)", flush=True)
    rows = []
    for path, sec, n in jobs:
        for seed in args.seeds:
            row = run_one(path, sec, seed, args.eaco_args.split())
            if "error" not in row:
                length = float(row["best_length"])
                known = D15112_OPTIMUM if path.stem == "d15112" else reference.get(path.stem)
                if known:
                    row["reference_length"] = known
                    row["gap_percent"] = 100.0 * (length / known - 1.0)
                if path.stem.startswith("rand"):
                    row["bhh_estimate"] = BHH * math.sqrt(n * SIDE**2)
                    row["over_bhh_percent"] = 100.0 * (length / row["bhh_estimate"] - 1.0)
            rows.append(row)
            show = {k: row.get(k) for k in ("instance", "seed", "best_length", "gap_percent",
                                            "over_bhh_percent", "tours_per_second",
                                            "peak_host_bytes", "peak_device_bytes",
                                            "wall_seconds", "stop_reason", "error")}
            print(json.dumps(show), flush=True)
    write_results(args.out, rows, date=datetime.date.today().isoformat(),
                  command=" ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
                  seeds={"instance_seeds": args.instance_seeds, "run_seeds": args.seeds})
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
