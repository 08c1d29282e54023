"""CPU (or GPU) time per iteration of the graph EACO colony, after compilation.

Measures ms per iteration (median over several compiled chunks) and tours per second for
``--ants`` ants on TSPLIB instances, without local search, and compares with ACOTSP (MMAS, 40
ants, one thread, measured on the lead's machine: eil51 0.28, kroA100 0.69, a280 3.8 ms).

Two colonies are timed: ``core`` (construction + MMAS pheromone rules, what ACOTSP's MMAS does)
and ``eaco`` (ERX crossover and inversion mutation on top, as the default EACO runs with 2-opt;
without 2-opt its defaults leave them off).

This machine's speed drifts by up to 1.5x from minute to minute (a shared host), so a fixed
reference time is only a rough yardstick. ``--acotsp PATH`` (an ACOTSP binary built
elsewhere; nothing of it is in this repository) times ACOTSP in the same process slot:
``--rounds`` alternations of our chunks and a ``--acotsp-seconds`` ACOTSP run on the same
instance, so both see the same machine; its ms per iteration is the run time over the last
iteration it reports (every 100). Pin the run to one core (``taskset -c 1``).

    python experiments/tsp_speed.py                      # 40 ants, eil51 kroA100 a280
    taskset -c 1 python experiments/tsp_speed.py --variants core --acotsp ~/ACOTSP/acotsp
    python experiments/tsp_speed.py --ants 1024 --instances pcb442 --variants core   # GPU
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
from pathlib import Path

ACOTSP_MS = {"eil51": 0.28, "kroA100": 0.69, "a280": 3.8}
RESULTS = Path(__file__).resolve().parent / "results" / "tsp_speed.json"


class ChunkTimer:
    """``minimize`` callback: seconds per iteration of every chunk after the first (warm-up),
    from the driver's compute seconds (compilation excluded); after every ``chunks`` timed
    chunks it calls ``between()`` (untimed: the driver counts only its compiled calls)."""

    def __init__(self, chunk: int, chunks: int, between=None) -> None:
        self.chunk, self.chunks, self.between = chunk, chunks, between
        self.seconds, self.per_iter = 0.0, []

    def __call__(self, state, progress) -> bool:
        elapsed, self.seconds = progress.seconds - self.seconds, progress.seconds
        if progress.iterations > self.chunk:  # the first chunk is the warm-up
            self.per_iter.append(elapsed / self.chunk)
            if self.between is not None and len(self.per_iter) % self.chunks == 0:
                self.between()
        return False


def acotsp_ms(binary: Path, name: str, seconds: float) -> float:
    """ACOTSP's MMAS, 40 ants, no local search, one run of ``seconds``: ms per iteration."""
    from acotsp_quality import run_acotsp, tsp_file  # sibling script in experiments/

    done = run_acotsp(binary, tsp_file(name), seconds, seed=1)["iterations"]
    if not done:
        raise RuntimeError("ACOTSP reported no iteration count")
    return 1e3 * seconds / done


def time_colony(problem, strategy, chunk: int, chunks: int, rounds: int = 1,
                acotsp: Path | None = None, acotsp_seconds: float = 3.0) -> dict:
    """Median ms/iteration over ``rounds`` x ``chunks`` compiled chunks of ``chunk``
    iterations (one run, after a warm-up chunk); with ``acotsp``, an ACOTSP run after each
    round."""
    import eaco_jax as ea

    aco: list[float] = []
    between = None
    if acotsp is not None:
        def between() -> None:
            aco.append(acotsp_ms(acotsp, problem.name, acotsp_seconds))

    timer = ChunkTimer(chunk, chunks, between)
    res = ea.minimize(problem, strategy, seed=0, iterations=(1 + rounds * chunks) * chunk,
                      chunk_size=chunk, callback=timer)
    per_iter = timer.per_iter
    ms = 1e3 * statistics.median(per_iter)
    return {
        "ms_per_iteration": ms,
        "ms_per_iteration_min": 1e3 * min(per_iter),
        "tours_per_second": strategy.num_ants / (ms / 1e3),
        "compile_seconds": res.compile_seconds,
        "best_length": float(res.best_cost),
        **({"acotsp_measured_ms": statistics.median(aco), "acotsp_measured_ms_min": min(aco),
            "acotsp_runs_ms": aco} if aco else {}),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--instances", nargs="+", default=["eil51", "kroA100", "a280"])
    ap.add_argument("--variants", nargs="+", default=["core", "eaco"], choices=["core", "eaco"])
    ap.add_argument("--chunk", type=int, default=50, help="iterations per compiled call")
    ap.add_argument("--chunks", type=int, default=10, help="timed calls (median taken)")
    ap.add_argument("--rounds", type=int, default=1,
                    help="alternations of timed chunks and ACOTSP runs")
    ap.add_argument("--acotsp", type=Path, default=None, help="ACOTSP binary to time alongside")
    ap.add_argument("--acotsp-seconds", type=float, default=3.0)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    import jax

    from eaco_jax.problems.tsp import load_tsplib
    from eaco_jax.strategies.graph_eaco import GraphEACO

    device = str(jax.devices()[0])
    rows = []
    for name in args.instances:
        problem = load_tsplib(name)
        for variant in args.variants:
            ga = ({"crossover": "erx", "mutation": "inversion"} if variant == "eaco"
                  else {"crossover": "none", "mutation": "none"})
            strategy = GraphEACO(num_ants=args.ants, local_search="none", **ga)
            aco = args.acotsp if args.ants == 40 and variant == "core" else None
            r = time_colony(problem, strategy, args.chunk, args.chunks, args.rounds, aco,
                            args.acotsp_seconds)
            ref = ACOTSP_MS.get(name) if args.ants == 40 else None
            r.update(instance=name, n=problem.n, variant=variant, ants=args.ants,
                     acotsp_ms=ref, ratio_to_acotsp=None if ref is None else
                     r["ms_per_iteration"] / ref)
            if "acotsp_measured_ms" in r:
                r["ratio_to_acotsp_measured"] = r["ms_per_iteration"] / r["acotsp_measured_ms"]
            rows.append(r)
            print(f"{name:>8} {variant:>5} ants={args.ants:<5} {r['ms_per_iteration']:9.2f} ms/it"
                  f" (min {r['ms_per_iteration_min']:.2f})  {r['tours_per_second']:10.0f} tours/s"
                  + (f"  ACOTSP {ref:.2f} ms  ratio {r['ratio_to_acotsp']:.1f}x" if ref else "")
                  + (f"  | ACOTSP here {r['acotsp_measured_ms']:.2f} ms (min "
                     f"{r['acotsp_measured_ms_min']:.2f})  ratio "
                     f"{r['ratio_to_acotsp_measured']:.2f}x" if "acotsp_measured_ms" in r else "")
                  + f"  (compile {r['compile_seconds']:.1f} s)", flush=True)
    record = {"device": device, "cpu_count": os.cpu_count(), "chunk": args.chunk,
              "chunks": args.chunks, "rounds": args.rounds,
              "acotsp_seconds": args.acotsp_seconds if args.acotsp else None, "rows": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
