"""Host work around the search of a TSP run: per chunk, and per run before the search.

Two measurements, each for one source tree (``--src``: a checkout whose ``eaco_jax`` is put
first on the import path, so two commits compare on one machine):

* ``chunk``: in one process, a time-bounded sparse run (one-iteration chunks) of a small colony
  on pr1002, repeated after a warm-up; host milliseconds per iteration = (wall seconds of
  ``minimize`` - its compile and search seconds) / iterations.
* ``setup``: ``eaco tsp FILE --iterations I`` as fresh processes with the on-disk program cache
  warm (one discarded run first); the record's ``timing`` (start-up, setup, compile, loop).

    python experiments/tsp_host_overhead.py --src . --label after \
        --instance out/tsp_large/rand10000_s1.tsp --out OUT.json
    python experiments/tsp_host_overhead.py --src /tmp/before --label before ...

Prints a table and writes JSON (``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from common import REPO, eaco_tsp, write_results

CHUNK_CODE = r"""
import json, sys, time
from eaco_jax.runs import tsp
from eaco_jax.driver.minimize import minimize
s = tsp.TspSettings("pr1002", sparse="on", max_new_edges=8, construction="moves", ants=8,
                    local_search="or-2opt", ls_best_k=8, preset="mmas", max_seconds=5.0,
                    merge_ants=4)
b = tsp.build(s)
minimize(b.problem, b.strategy, seed=0, params=b.params, **b.budget)  # warm-up
out = []
for _ in range(int(sys.argv[1])):
    t0 = time.perf_counter()
    r = minimize(b.problem, b.strategy, seed=0, params=b.params, **b.budget)
    wall = time.perf_counter() - t0
    out.append({"iterations": int(r.iterations), "wall_seconds": wall,
                "host_ms_per_iteration": 1000 * (wall - r.seconds) / r.iterations})
print(json.dumps(out))
"""


def env_for(src: Path, cache: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src.resolve()), EACO_COMPILE_CACHE=str(cache))
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    return env


def chunk_overhead(src: Path, repeats: int, cache: Path) -> list[dict]:
    out = subprocess.run([sys.executable, "-c", CHUNK_CODE, str(repeats)], env=env_for(src, cache),
                         capture_output=True, text=True, check=True, cwd=tempfile.gettempdir())
    return json.loads(out.stdout.strip().splitlines()[-1])


def setup_runs(src: Path, instance: Path, iterations: int, repeats: int, extra: list[str],
               cache: Path) -> list[dict]:
    rows = []
    for i in range(repeats + 1):  # the first fills the caches and is discarded
        done = eaco_tsp([instance.resolve(), "--iterations", iterations, "--seed", 0, "--quiet",
                         *extra], env=env_for(src, cache), cwd=tempfile.gettempdir())
        if done["error"]:
            raise RuntimeError(f"eaco tsp failed: {done['error']}")
        rec = done["record"]
        if i:
            rows.append({**rec["timing"], "best_length": rec.get("best_length")})
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", type=Path, default=REPO)
    ap.add_argument("--label", default="this tree")
    ap.add_argument("--instance", type=Path, required=True, help="a .tsp file for the setup runs")
    ap.add_argument("--iterations", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--eaco-args", default="--sparse on --max-new-edges 128 --construction moves "
                    "--merge-ants 96 --local-search or-2opt --ls-best-k 96 --preset mmas")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as cache:
        chunk = chunk_overhead(args.src, args.repeats, Path(cache) / "chunk")
        setup = setup_runs(args.src, args.instance, args.iterations, args.repeats,
                           args.eaco_args.split(), Path(cache) / "setup")
    summary = {
        "host_ms_per_iteration_median": statistics.median(r["host_ms_per_iteration"]
                                                          for r in chunk),
        "setup_seconds_median": statistics.median(r["setup_seconds"] for r in setup),
        "compile_seconds_median": statistics.median(r["compile_seconds"] for r in setup),
        "total_seconds_median": statistics.median(r["total_seconds"] for r in setup),
    }
    print(f"{'tree':<12} {'host ms/it':>10} {'setup s':>8} {'compile s':>9} {'total s':>8}")
    print(f"{args.label:<12} {summary['host_ms_per_iteration_median']:>10.3f} "
          f"{summary['setup_seconds_median']:>8.2f} {summary['compile_seconds_median']:>9.2f} "
          f"{summary['total_seconds_median']:>8.2f}")
    write_results(args.out, [{"part": "chunk", **r} for r in chunk]
                  + [{"part": "setup", **r} for r in setup],
                  label=args.label, src=str(args.src), instance=str(args.instance),
                  eaco_args=args.eaco_args, iterations=args.iterations, summary=summary,
                  command=" ".join(["tsp_host_overhead.py", *(argv or sys.argv[1:])]))


if __name__ == "__main__":
    main()
