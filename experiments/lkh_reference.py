"""LKH-3 reference tours for the random uniform instances of ``tsp_large.py`` (issue 33).

The issue measures gaps on random 10,000- and 100,000-city instances against LKH-3 run here.
This script writes each instance with ``tsp_large.random_instance`` (the very file, and so the
very integer EUC_2D coordinates, that ``eaco tsp`` reads), runs an LKH-3 binary on it with the
settings below (one run, POPMUSIC candidates, bounded trials and time), reads LKH's tour back,
checks it is a permutation and recomputes its length in int64 with the project's TSPLIB
distance rule. One JSON per instance goes to ``--out-dir`` (length, LKH's printed lower bound,
settings, LKH version, CPU seconds, date), and its tour beside it as ``NAME.tour`` (TSPLIB
TOUR format) for instances up to ``--keep-tour-max`` cities, and LKH's output as
``NAME.lkh.log``.

LKH's lower bound is its Held-Karp ascent over the candidate graph (with POPMUSIC candidates a
sparse graph), the figure LKH prints as "Lower bound"; ``gap_to_lower_bound_percent`` is the
tour's distance from it in LKH's own terms, not a proven bound on the optimum.

LKH is not part of the project (its licence is research use only): build it elsewhere and pass
the binary. Without one the script says so in one line and exits 0 (CI has no LKH).

    python experiments/lkh_reference.py --lkh /tmp/lkh/LKH --sizes 10000
    python experiments/lkh_reference.py --lkh /tmp/lkh/LKH --sizes 100000 --max-trials 100 \
        --time-limit 600 --initial-period 100
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import write_results
from tsp_large import BHH, LKH_DIR, SIDE, find_file, known_optimum, random_instance

OUT_DIR = LKH_DIR


def lkh_binary(text: str | None) -> Path | None:
    """The LKH executable at ``text`` (a path or a name on PATH), or None when absent."""
    if not text:
        return None
    found = shutil.which(text) if os.sep not in text else None
    path = Path(found) if found else Path(text)
    return path if path.is_file() and os.access(path, os.X_OK) else None


def lkh_version(binary: Path) -> str | None:
    """LKH's version from the README.txt of its source folder ("Version 3.0.6 - May 2019").

    LKH prints no version; its distribution's README names it, beside the binary."""
    for folder in (binary.parent, binary.parent.parent):
        readme = folder / "README.txt"
        if readme.is_file():
            m = re.search(r"\(Version ([0-9.]+)", readme.read_text(errors="replace"))
            if m:
                return m.group(1)
    return None


def parameters(problem: Path, tour: Path, *, max_trials: int, time_limit: float, seed: int,
               max_candidates: int, initial_period: int | None) -> dict[str, object]:
    """The LKH parameter file's entries, in order (recorded in the result as they ran)."""
    par: dict[str, object] = {
        "PROBLEM_FILE": str(problem),
        "TOUR_FILE": str(tour),
        "RUNS": 1,
        "SEED": seed,
        "CANDIDATE_SET_TYPE": "POPMUSIC",
        "MAX_CANDIDATES": max_candidates,
        "MAX_TRIALS": max_trials,
        "TIME_LIMIT": time_limit,
        "TRACE_LEVEL": 1,
    }
    if initial_period is not None:
        par["INITIAL_PERIOD"] = initial_period
    return par


def parse_output(text: str) -> dict[str, float | bool | None]:
    """LKH's printed lower bound, ascent time, best cost and run time (None where absent)."""

    def grab(pattern: str) -> float | None:
        m = re.search(pattern, text)
        return float(m.group(1)) if m else None

    return {
        "lower_bound": grab(r"Lower bound = ([0-9.eE+-]+)"),
        "ascent_seconds": grab(r"Ascent time = ([0-9.]+) sec"),
        "cost_min": grab(r"Cost\.min = ([0-9]+)"),
        "preprocessing_seconds": grab(r"Preprocessing time = ([0-9.]+) sec"),
        "run_seconds": grab(r"Time\.min = ([0-9.]+) sec"),
        "trials": grab(r"Trials\.min = ([0-9]+)"),
        "time_limit_hit": "Time limit exceeded" in text,
    }


def read_tour(path: Path, n: int) -> np.ndarray:
    """A TSPLIB TOUR file's cities as 0-based int64 ids, checked to be a permutation of n."""
    from eaco_jax.errors import ProblemError
    from eaco_jax.problems.tsp_exact import validate_tour

    ids: list[int] = []
    inside = False
    for line in path.read_text().splitlines():
        s = line.strip()
        if s.upper().startswith("TOUR_SECTION"):
            inside = True
            continue
        if inside:
            if s == "-1" or s.upper() == "EOF":
                break
            ids.extend(int(v) for v in s.split())
    if not inside:
        raise ProblemError(f"{path}: no TOUR_SECTION; is it an LKH tour file?")
    return validate_tour(np.asarray(ids, dtype=np.int64) - 1, n)


def tour_length(instance: Path, tour: np.ndarray) -> int:
    """The exact int64 length of ``tour`` on the TSPLIB file ``instance`` (its own metric),
    from the coordinates the project's reader gives ``eaco tsp``."""
    from eaco_jax.problems.tsplib import pair_distances, read_tsplib

    inst = read_tsplib(instance)
    xy = inst.coords
    d = pair_distances(xy[tour], xy[np.roll(tour, -1)], inst.edge_weight_type)
    return int(d.astype(np.int64).sum())


def run_lkh(binary: Path, instance: Path, par: dict[str, object], nice: int,
            folder: Path, log: Path) -> tuple[str, float, float]:
    """Run LKH once, its output streamed to ``log``: that output, its CPU seconds (user +
    system, from the OS) and wall seconds."""
    par_file = folder / f"{instance.stem}.par"
    par_file.write_text("".join(f"{k} = {v}\n" for k, v in par.items()))
    argv = [str(binary), str(par_file)]
    if nice:
        argv = ["nice", "-n", str(nice), *argv]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        done = subprocess.run(argv, stdout=fh, stderr=subprocess.STDOUT,
                              stdin=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    text = log.read_text(errors="replace")
    if done.returncode:
        raise SystemExit(f"LKH failed on {instance.name} (exit {done.returncode}): "
                         f"{text.strip()[-300:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return text, cpu, wall


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lkh", help="path to an LKH-3 binary (absent: skip)")
    ap.add_argument("--sizes", type=int, nargs="*", default=[10_000])
    ap.add_argument("--instance-seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--instances", nargs="*", default=[],
                    help="named TSPLIB instances too (d15112: how far LKH's settings end "
                         "from a known optimum)")
    ap.add_argument("--max-trials", type=int, default=1000)
    ap.add_argument("--time-limit", type=float, default=1200.0,
                    help="LKH's TIME_LIMIT: CPU seconds of search after preprocessing")
    ap.add_argument("--lkh-seed", type=int, default=1, help="LKH's SEED")
    ap.add_argument("--max-candidates", type=int, default=5)
    ap.add_argument("--initial-period", type=int, default=None,
                    help="LKH's INITIAL_PERIOD of the ascent (default: LKH's, n / 2)")
    ap.add_argument("--nice", type=int, default=15)
    ap.add_argument("--keep-tour-max", type=int, default=20_000,
                    help="store NAME.tour beside the JSON up to this many cities")
    ap.add_argument("--work", type=Path, default=Path("out/tsp_large"))
    ap.add_argument("--out-dir", type=Path, default=OUT_DIR)
    args = ap.parse_args(argv)
    binary = lkh_binary(args.lkh)
    if binary is None:
        print(f"LKH binary not found ({args.lkh or 'no --lkh given'}): skipped; build LKH-3 "
              "and pass --lkh PATH")
        return 0
    version = lkh_version(binary)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    jobs: list[tuple[Path, int, int | None]] = [
        (random_instance(args.work, n, iseed), n, iseed)
        for n in args.sizes for iseed in args.instance_seeds]
    for name in args.instances:
        path = find_file(name)
        if path is None:
            raise SystemExit(f"{name}: no such instance (a bundled name or a .tsp path)")
        from eaco_jax.problems.tsplib import read_tsplib

        jobs.append((path, read_tsplib(path).dimension, None))
    for instance, n, iseed in jobs:
        with tempfile.TemporaryDirectory() as tmp:
            tour_file = Path(tmp) / f"{instance.stem}.tour"
            par = parameters(instance.resolve(), tour_file, max_trials=args.max_trials,
                             time_limit=args.time_limit, seed=args.lkh_seed,
                             max_candidates=args.max_candidates,
                             initial_period=args.initial_period)
            stdout, cpu, wall = run_lkh(binary, instance, par, args.nice, Path(tmp),
                                        args.out_dir / f"{instance.stem}.lkh.log")
            tour = read_tour(tour_file, n)
            tour_text = tour_file.read_text()
        length = tour_length(instance, tour)
        printed = parse_output(stdout)
        if printed["cost_min"] is not None and int(printed["cost_min"]) != length:
            raise SystemExit(f"{instance.stem}: LKH reports {printed['cost_min']:.0f}, "
                             f"the tour recomputed here is {length}: coordinates differ")
        bound = printed["lower_bound"]
        row = {
            "instance": instance.stem, "n": n, "instance_seed": iseed, "length": length,
            "lkh_lower_bound": bound,
            "gap_to_lower_bound_percent": None if not bound else 100.0 * (length / bound - 1),
            "cpu_seconds": cpu, "wall_seconds": wall, "lkh_printed": printed,
            "parameters": {k: v for k, v in par.items()
                           if k not in ("PROBLEM_FILE", "TOUR_FILE")},
            "nice": args.nice, "lkh_version": version, "lkh_binary": str(binary),
        }
        optimum = known_optimum(instance)
        if optimum:
            row["optimum"] = optimum
            row["gap_to_optimum_percent"] = 100.0 * (length / optimum - 1.0)
        if iseed is not None:
            row["bhh_estimate"] = BHH * (n * SIDE**2) ** 0.5
            row["over_bhh_percent"] = 100.0 * (length / row["bhh_estimate"] - 1.0)
        out = args.out_dir / f"{instance.stem}.json"
        write_results(out, [row], date=datetime.datetime.now(datetime.UTC).isoformat(
            timespec="seconds"), command=" ".join([Path(sys.argv[0]).name, *(
                argv if argv is not None else sys.argv[1:])]),
            seeds={"instance_seed": iseed, "lkh_seed": args.lkh_seed})
        if n <= args.keep_tour_max:
            (args.out_dir / f"{instance.stem}.tour").write_text(tour_text)
        print(json.dumps({k: row.get(k) for k in (
            "instance", "length", "lkh_lower_bound", "gap_to_lower_bound_percent",
            "gap_to_optimum_percent", "over_bhh_percent", "cpu_seconds")}), flush=True)
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
