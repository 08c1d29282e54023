"""Batched 2-opt / Or-opt: the greedy acceptance of a step's moves, one by one or in rounds.

Each step of ``two_opt`` (``local_search="2opt" | "or-2opt"``) takes the best ``moves_per_step``
moves of a tour and accepts, greedily by gain, those disjoint from the better accepted ones.
Until session 12 this was a ``fori_loop`` of one decision per move (32 dependent steps, each a
few kernels on a GPU, inside every step of the search); now it runs in parallel rounds
(``_greedy_disjoint``) with the same result. This script times whole colony iterations
(``GraphEACO`` with local search, through ``minimize``) with each acceptance, checks that both
reach the same best length after the same iterations (same moves, same tours), and writes a
table and JSON. The sequential version lives only here, as the reference being replaced.

    python experiments/local_search_acceptance_speed.py --cases pcb442:1024 pr1002:384
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from common import find_instance, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "local_search_acceptance_speed.json"


def sequential_greedy(valid, overlap, budget):
    """The acceptance before session 12: one decision per move, in order."""
    import jax
    import jax.numpy as jnp

    def accept(t, acc):
        ok = valid[t] & ~jnp.any(acc & overlap[t]) & (acc.sum() < budget)
        return acc.at[t].set(ok)

    return jax.lax.fori_loop(0, valid.shape[0], accept, jnp.zeros_like(valid))


def time_colony(problem, ants: int, local_search: str, iterations: int, seed: int) -> dict:
    """ms per colony iteration (after compilation) and the best length after ``iterations``."""
    import jax
    import numpy as np

    from eaco_jax import minimize
    from eaco_jax.driver import minimize as driver
    from eaco_jax.driver import program_cache
    from eaco_jax.strategies.graph_eaco import GraphEACO

    driver.clear_compiled()  # each variant traces and compiles its own chunk
    program_cache.set_folder(None)  # a loaded program would not see the patched acceptance
    jax.clear_caches()
    strategy = GraphEACO(num_ants=ants, local_search=local_search)
    t0 = time.perf_counter()
    res = minimize(problem, strategy, seed=seed, iterations=iterations, chunk_size=5)
    wall = time.perf_counter() - t0
    run = res.seconds - res.compile_seconds
    return {"ms_per_iteration": 1000 * run / iterations, "compile_seconds": res.compile_seconds,
            "wall_seconds": wall, "best": float(np.min(np.asarray(res.best_cost)))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["pcb442:1024", "pr1002:384"],
                    help="INSTANCE:ANTS")
    ap.add_argument("--local-search", default="or-2opt")
    ap.add_argument("--iterations", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--data-dir", type=Path, action="append")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    from eaco_jax.ops import local_search

    rounds = local_search._greedy_disjoint
    rows = []
    print(f"{'instance':>8} {'ants':>6} {'acceptance':>10} {'ms/it':>8} {'compile s':>9} "
          f"{'best':>10}")
    for case in args.cases:
        name, ants = case.split(":")
        problem = find_instance(name, args.data_dir)
        got = {}
        for variant, fn in (("sequential", sequential_greedy), ("rounds", rounds)):
            local_search._greedy_disjoint = fn
            try:
                r = time_colony(problem, int(ants), args.local_search, args.iterations,
                                args.seed)
            finally:
                local_search._greedy_disjoint = rounds
            got[variant] = r
            rows.append({"instance": name, "ants": int(ants), "acceptance": variant,
                         "local_search": args.local_search, "iterations": args.iterations,
                         **r})
            print(f"{name:>8} {ants:>6} {variant:>10} {r['ms_per_iteration']:8.2f} "
                  f"{r['compile_seconds']:9.1f} {r['best']:10.0f}", flush=True)
        rows[-1]["same_best_as_sequential"] = got["rounds"]["best"] == got["sequential"]["best"]
        rows[-1]["speedup"] = (got["sequential"]["ms_per_iteration"]
                               / got["rounds"]["ms_per_iteration"])
        print(f"{'':>8} speed-up {rows[-1]['speedup']:.2f}x, same best: "
              f"{rows[-1]['same_best_as_sequential']}")
    write_results(args.out, rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
