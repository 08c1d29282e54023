"""TSP at 10,000-100,000 cities (issue 33): ``eaco tsp FILE --max-seconds S`` as fresh processes.

Instances: random uniform EUC_2D instances (DyNACO's setting: integer coordinates in
[0, 10^6), one file per ``--instance-seeds`` seed and ``--sizes`` size, written to ``--work``),
and the named TSPLIB instances of ``--instances`` (``d15112`` ships with the package; a path
or a data folder's name works too: ``common.data_dirs``). Each (instance, run seed of
``--seeds``) is one fresh ``python -m eaco_jax tsp FILE --max-seconds S --clock call --seed
SEED`` process: S counts from the process's start (start-up, reading, candidate lists,
compilation and the first tour included; ``--clock run``: the search loop's compute only, as
before), so a gap is "in S seconds from the call". ``--seconds`` gives S per size (one value,
or one per size), ``--instance-seconds`` S of the named instances (75.9, Focused ACO's d15112
figure), ``--eaco-args`` extra flags for every run.

Each row: the tour length; ``gap_percent`` against TSPLIB's optimum (named instances) or the
LKH-3 tour run here (random instances with a reference in ``results/tsp_large/lkh``, written
by ``lkh_reference.py``; ``--reference FILE.json`` replaces them), ``reference`` says which;
for random instances also the length over the Beardwood-Halton-Hammersley estimate
0.7124 sqrt(n A) of a random uniform optimum (an estimate, not a gap); tours/s, peak host
memory (RSS) and device memory where the backend reports it (JAX's ``memory_stats``);
``wall_seconds`` (this script's clock around the process, exit included), ``clock`` and
``budget_seconds`` (the budget and what it counted), ``call_seconds`` (the run's own clock
from its process start to the end of the search) and ``timing`` (start-up, setup,
compilation and loop seconds of that).
Instance seeds (which instances) and run seeds (which colony) are separate lists; nothing
here chooses settings. ``--append`` adds the rows to an existing ``--out`` (one file from
several calls), ``--process-timeout`` kills a run that overruns (recorded as an error).

    python experiments/tsp_large.py --sizes 10000 --seconds 18 --seeds 0 1 2     # GPU
    python experiments/tsp_large.py --sizes --instances d15112 --seeds 0 1 2     # GPU
    python experiments/tsp_large.py --sizes 2000 --seconds 10 --seeds 0   # CPU smoke
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import sys
from pathlib import Path

import numpy as np
from common import data_dirs, eaco_tsp, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_large.json"
#: the side of the random instances' square, and the BHH constant of a random uniform tour
SIDE, BHH = 1_000_000, 0.7124
#: LKH-3 reference tours of the random instances (``lkh_reference.py``), one JSON each
LKH_DIR = Path(__file__).resolve().parent / "results" / "tsp_large" / "lkh"


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


def reference_lengths(folder: Path = LKH_DIR) -> dict[str, int]:
    """{instance name: LKH-3 tour length} from the stored references (empty when none)."""
    out: dict[str, int] = {}
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        for row in json.loads(path.read_text()).get("rows", []):
            if "length" in row:
                out[row["instance"]] = int(row["length"])
    return out


def find_file(name: str) -> Path | None:
    """A named instance: a path, the package's (``d15112`` ships with it), or a data folder's."""
    if name.endswith(".tsp") or "/" in name:
        return Path(name) if Path(name).is_file() else None
    from eaco_jax.problems.tsp import bundled_path

    found = bundled_path(name)
    if found is not None:
        return found
    for d in data_dirs():
        if (d / f"{name}.tsp").is_file():
            return d / f"{name}.tsp"
    return None


def known_optimum(path: Path) -> float | None:
    """TSPLIB's optimum of a named instance (the package's optima), None for others."""
    from eaco_jax.problems.tsp import bundled_optima, large_optima

    optima = {**large_optima(), **bundled_optima()}
    return optima.get(path.stem)


def run_one(path: Path, seconds: float, seed: int, extra: list[str],
            timeout: float | None = None, clock: str = "call") -> dict:
    """One fresh ``eaco tsp`` process: its record (without the tour) and the wall clock."""
    done = eaco_tsp([path, "--max-seconds", seconds, "--clock", clock, "--seed", seed, *extra],
                    timeout=timeout)
    if done["error"]:
        return {"instance": path.stem, "seed": seed, "error": done["error"],
                "wall_seconds": done["wall_seconds"], "clock": clock, "budget_seconds": seconds}
    rec = done["record"]
    history = rec.pop("history_best", [])
    timing = rec.get("timing") or {}
    return {**rec, "wall_seconds": done["wall_seconds"], "budget_seconds": seconds,
            "clock": timing.get("clock", "run"), "call_seconds": timing.get("total_seconds"),
            "history_points": len(history), "argv": done["argv"]}


def score(row: dict, path: Path, n: int, optimum: float | None,
          lkh: dict[str, int]) -> dict:
    """The row with its gaps: to TSPLIB's optimum (named instances), to the LKH-3 tour run
    here (random instances with a stored reference) and over the BHH estimate (random)."""
    if "error" in row:
        return row
    length = float(row["best_length"])
    if optimum:
        row["reference_length"] = optimum
        row["reference"] = "optimum"
        row["gap_percent"] = 100.0 * (length / optimum - 1.0)
    elif path.stem in lkh:
        row["reference_length"] = lkh[path.stem]
        row["reference"] = "lkh-3"
        row["gap_percent"] = 100.0 * (length / lkh[path.stem] - 1.0)
    if path.stem in lkh:
        row["lkh_length"] = lkh[path.stem]
        row["gap_to_lkh_percent"] = 100.0 * (length / lkh[path.stem] - 1.0)
    if path.stem.startswith("rand"):
        row["bhh_estimate"] = BHH * math.sqrt(n * SIDE**2)
        row["over_bhh_percent"] = 100.0 * (length / row["bhh_estimate"] - 1.0)
    return row


def rescore(source: Path, out: Path, lkh: dict[str, int], argv: list[str] | None) -> None:
    """The rows of an earlier result file scored again (a reference stored since), written to
    ``out`` with the source file's command and this one."""
    old = json.loads(source.read_text())
    rows = []
    for row in old["rows"]:
        path = Path(f"{row['instance']}.tsp")
        n = int(row.get("n") or 0)
        rows.append(score(dict(row), path, n, known_optimum(path), lkh))
    command = " ".join([Path(sys.argv[0]).name, *(argv if argv is not None else sys.argv[1:])])
    write_results(out, rows, date=datetime.date.today().isoformat(), command=command,
                  source={"file": str(source), "command": old.get("command"),
                          "date": old.get("date"), "info": old.get("info")},
                  seeds=old.get("seeds"))
    for row in rows:
        print(json.dumps({k: row.get(k) for k in ("instance", "seed", "best_length",
                                                   "gap_percent", "reference",
                                                   "over_bhh_percent")}))
    print(f"wrote {out}")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[10_000, 100_000],
                    help="random uniform instance sizes (none: only --instances)")
    ap.add_argument("--seconds", type=float, nargs="+", default=[18.0, 172.0])
    ap.add_argument("--instance-seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--instances", nargs="*", default=[],
                    help="named TSPLIB instances or .tsp paths to run too (e.g. d15112)")
    ap.add_argument("--instance-seconds", "--d15112-seconds", type=float, default=75.9,
                    help="budget of each --instances run (Focused ACO's 75.9 s on d15112)")
    ap.add_argument("--no-d15112", action="store_true",
                    help="kept for recorded commands: d15112 runs only when --instances names it")
    ap.add_argument("--reference", type=Path,
                    help="JSON {instance: reference length}; default: the stored LKH-3 tours "
                         "of experiments/results/tsp_large/lkh")
    ap.add_argument("--eaco-args", default="", help="extra flags for every eaco tsp run")
    ap.add_argument("--clock", choices=("call", "run"), default="call",
                    help="what --max-seconds counts in each run: call (from the process's "
                         "start, the targets' measure) or run (the search loop's compute)")
    ap.add_argument("--process-timeout", type=float, default=None,
                    help="kill a run after this many seconds (recorded as an error)")
    ap.add_argument("--append", action="store_true",
                    help="keep the rows already in --out (one file from several calls)")
    ap.add_argument("--rescore", type=Path,
                    help="run nothing: score the rows of this earlier result file against "
                         "today's references and write them to --out")
    ap.add_argument("--work", type=Path, default=Path("out/tsp_large"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    seconds = args.seconds if len(args.seconds) == len(args.sizes) else \
        [args.seconds[0]] * len(args.sizes)
    lkh = reference_lengths() if args.reference is None else \
        {k: int(v) for k, v in json.loads(args.reference.read_text()).items()}
    if args.rescore:
        rescore(args.rescore, args.out, lkh, argv)
        return
    named = []  # checked before any random instance is written
    for name in args.instances:
        path = find_file(name)
        if path is None:
            raise SystemExit(f"{name}: no such instance (bundled: d15112 and the small ones; "
                             "or pass a path to a .tsp file)")
        named.append((path, args.instance_seconds, 0))
    jobs = [(random_instance(args.work, n, s), sec, n) for n, sec in zip(args.sizes, seconds,
                                                                          strict=True)
            for s in args.instance_seeds] + named
    rows, commands = [], []
    if args.append and args.out.is_file():
        old = json.loads(args.out.read_text())
        rows = list(old.get("rows", []))
        commands = list(old.get("commands", [old.get("command")]))
    command = " ".join([Path(sys.argv[0]).name,
                        *(argv if argv is not None else sys.argv[1:])])
    for path, sec, n in jobs:
        for seed in args.seeds:
            row = run_one(path, sec, seed, args.eaco_args.split(), args.process_timeout,
                          args.clock)
            row = score(row, path, n or int(row.get("n", 0)), known_optimum(path), lkh)
            row["command"] = command
            rows.append(row)
            show = {k: row.get(k) for k in ("instance", "seed", "best_length", "gap_percent",
                                            "reference", "over_bhh_percent",
                                            "tours_per_second", "peak_host_bytes",
                                            "peak_device_bytes", "wall_seconds",
                                            "clock", "budget_seconds", "call_seconds",
                                            "stop_reason", "error")}
            print(json.dumps(show), flush=True)
    write_results(args.out, rows, date=datetime.date.today().isoformat(), command=command,
                  commands=[c for c in commands if c] + [command],
                  seeds={"instance_seeds": args.instance_seeds, "run_seeds": args.seeds})
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
