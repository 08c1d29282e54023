"""CPU (or GPU) time per iteration of the graph EACO colony, after compilation.

Measures ms per iteration (median over several compiled chunks) and tours per second for
``--ants`` ants on TSPLIB instances, without local search, and compares with ACOTSP (MMAS, 40
ants, one thread, measured on the lead's machine: eil51 0.28, kroA100 0.69, a280 3.8 ms).

Two colonies are timed: ``core`` (construction + MMAS pheromone rules, what ACOTSP's MMAS does)
and ``eaco`` (the default EACO with ERX crossover and inversion mutation on top).

    python experiments/tsp_speed.py                      # 40 ants, eil51 kroA100 a280
    python experiments/tsp_speed.py --ants 1024 --instances pcb442 --variants core   # GPU
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

ACOTSP_MS = {"eil51": 0.28, "kroA100": 0.69, "a280": 3.8}
RESULTS = Path(__file__).resolve().parent / "results" / "tsp_speed.json"


def time_colony(problem, strategy, chunk: int, chunks: int) -> dict:
    """Compile one chunk of ``chunk`` iterations, run ``chunks`` of them, median ms/iteration."""
    import jax

    from eaco_jax.minimize import init_states, make_chunk_fn

    state = init_states(strategy, problem, [0], None)
    t0 = time.perf_counter()
    fn = make_chunk_fn(strategy, chunk, batched=False).lower(problem, state).compile()
    compile_s = time.perf_counter() - t0
    state, _ = fn(problem, state)  # warm-up
    jax.block_until_ready(state)
    per_iter = []
    for _ in range(chunks):
        t0 = time.perf_counter()
        state, _ = fn(problem, state)
        jax.block_until_ready(state)
        per_iter.append((time.perf_counter() - t0) / chunk)
    ms = 1e3 * statistics.median(per_iter)
    return {
        "ms_per_iteration": ms,
        "ms_per_iteration_min": 1e3 * min(per_iter),
        "tours_per_second": strategy.num_ants / (ms / 1e3),
        "compile_seconds": compile_s,
        "best_length": float(state.best_cost),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--instances", nargs="+", default=["eil51", "kroA100", "a280"])
    ap.add_argument("--variants", nargs="+", default=["core", "eaco"], choices=["core", "eaco"])
    ap.add_argument("--chunk", type=int, default=50, help="iterations per compiled call")
    ap.add_argument("--chunks", type=int, default=10, help="timed calls (median taken)")
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
            ga = {} if variant == "eaco" else {"crossover": "none", "mutation": "none"}
            strategy = GraphEACO(num_ants=args.ants, local_search="none", **ga)
            r = time_colony(problem, strategy, args.chunk, args.chunks)
            ref = ACOTSP_MS.get(name) if args.ants == 40 else None
            r.update(instance=name, n=problem.n, variant=variant, ants=args.ants,
                     acotsp_ms=ref, ratio_to_acotsp=None if ref is None else
                     r["ms_per_iteration"] / ref)
            rows.append(r)
            print(f"{name:>8} {variant:>5} ants={args.ants:<5} {r['ms_per_iteration']:9.2f} ms/it"
                  f"  {r['tours_per_second']:10.0f} tours/s"
                  + (f"  ACOTSP {ref:.2f} ms  ratio {r['ratio_to_acotsp']:.1f}x" if ref else "")
                  + f"  (compile {r['compile_seconds']:.1f} s)", flush=True)
    record = {"device": device, "cpu_count": os.cpu_count(), "chunk": args.chunk,
              "chunks": args.chunks, "rows": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
