"""Where the batched 2-opt / Or-opt spends a colony's local search: steps, moves and time.

The vmapped ``while_loop`` of ``ops.local_search.two_opt`` runs as many steps as its slowest
tour needs, and each step evaluates every city's candidate moves in every tour (on an H100
~0.9 ms for 384 pr1002 tours, ~0.2 ms for 16: the gathers, not kernel launches). This
script polishes one colony's first-iteration tours (``GraphEACO``'s construction from
uniform pheromone, alpha 1, beta 2, on the candidate lists) with each ``moves_per_step``
and move cap, and prints ms per call (median after compilation), the
steps of the slowest tour and of the mean one, moves per tour and the mean gap after the
search, also over ``--neighbors`` (the first K candidates per city). It is the evidence
behind ``GraphEACO.ls_moves_per_step``'s default.

    python experiments/local_search_steps.py --cases pcb442:1024 pr1002:384 \\
        --moves-per-step 8 16 32 64 128 256
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
from pathlib import Path

from common import find_instance, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "local_search_steps.json"


def profile(problem, ants: int, per_step: int, cap: int | None, or_opt: bool,
            seed: int, repeats: int, neighbors: int | None = None) -> dict:
    """One setting on one colony: time, steps, moves and the gap after the search."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from eaco_jax.ops.construction import tour_lengths
    from eaco_jax.ops.local_search import two_opt
    from eaco_jax.strategies.tour_base import build

    dist = jnp.asarray(problem.dist, jnp.float32)
    n = dist.shape[0]
    tours = build(jax.random.key(seed), jnp.ones((n, n), jnp.float32), problem, ants,
                  jnp.float32(1.0), jnp.float32(2.0))
    lists = problem.neighbors
    if neighbors is not None:
        if lists is None:
            raise SystemExit(f"{problem.name} has no candidate lists to take {neighbors} of")
        lists = lists[:, :neighbors]

    def run(t):
        return two_opt(t, dist, lists, cap, moves_per_step=per_step, or_opt=or_opt,
                       return_steps=True)

    t0 = time.perf_counter()
    out, moves, steps = jax.block_until_ready(run(tours))
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run(tours))
        times.append(time.perf_counter() - t0)
    before = np.asarray(tour_lengths(dist, tours))
    after = np.asarray(tour_lengths(dist, out))
    steps, moves = np.asarray(steps), np.asarray(moves)
    return {"ms_per_call": 1000 * statistics.median(times), "compile_seconds": compile_s,
            "steps_max": int(steps.max()), "steps_mean": float(steps.mean()),
            "moves_mean": float(moves.mean()), "moves_max": int(moves.max()),
            "gap_before_percent": float(100 * (before.mean() / problem.optimum - 1)),
            "gap_after_percent": float(100 * (after.mean() / problem.optimum - 1)),
            "best_after_percent": float(100 * (after.min() / problem.optimum - 1))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["pcb442:1024", "pr1002:384"],
                    help="INSTANCE:ANTS")
    ap.add_argument("--moves-per-step", type=int, nargs="+", default=[8, 16, 32, 64, 128])
    ap.add_argument("--caps", nargs="+", default=["none"],
                    help="move caps per tour ('none' = the default 4 n)")
    ap.add_argument("--neighbors", type=int, nargs="+", default=[0],
                    help="candidates per city the search scans (0: all of the lists)")
    ap.add_argument("--local-search", choices=["2opt", "or-2opt"], default="or-2opt")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--data-dir", type=Path, action="append")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    rows = []
    print(f"{'instance':>8} {'ants':>5} {'k':>3} {'mps':>4} {'cap':>5} {'ms':>8} {'steps max':>9} "
          f"{'mean':>7} {'moves':>7} {'gap in':>7} {'gap out':>8} {'best':>7}")
    for case in args.cases:
        name, ants = case.split(":")
        problem = find_instance(name, args.data_dir)
        for cap, k, mps in itertools.product(args.caps, args.neighbors, args.moves_per_step):
            c = None if cap == "none" else int(cap)
            r = profile(problem, int(ants), mps, c, args.local_search == "or-2opt",
                        args.seed, args.repeats, k or None)
            rows.append({"instance": name, "ants": int(ants), "moves_per_step": mps,
                         "cap": c, "neighbors": k or None, "local_search": args.local_search,
                         **r})
            print(f"{name:>8} {ants:>5} {k or 'all':>3} {mps:>4} {cap:>5} "
                  f"{r['ms_per_call']:8.2f} "
                  f"{r['steps_max']:9d} {r['steps_mean']:7.1f} {r['moves_mean']:7.1f} "
                  f"{r['gap_before_percent']:6.1f}% {r['gap_after_percent']:7.2f}% "
                  f"{r['best_after_percent']:6.2f}%", flush=True)
    write_results(args.out, rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
