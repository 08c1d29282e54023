"""Batched 2-opt / Or-opt: the greedy acceptance of a step's moves, one by one or in rounds.

Each step of ``ops.local_search.two_opt`` takes the best ``moves_per_step`` moves of a tour and
accepts, greedily by gain, those disjoint from the better accepted ones: in parallel rounds
(``acceptance="rounds"``, the default) or one decision per move (``"sequential"``, a
``fori_loop`` of dependent steps, each a few kernels on a GPU). This script polishes one
colony's first-iteration tours (``GraphEACO``'s construction from uniform pheromone, alpha 1,
beta 2, on the candidate lists) with each acceptance, prints the ms per ``two_opt`` call
(median after compilation) and checks that both return the same tours, and writes a JSON.

    python experiments/local_search_acceptance_speed.py --cases pcb442:1024 pr1002:384
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from common import find_instance, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "local_search_acceptance_speed.json"


def time_search(problem, tours, or_opt: bool, per_step: int, acceptance: str,
                repeats: int) -> tuple[dict, object]:
    """ms per ``two_opt`` call on ``tours`` (median of ``repeats`` after compilation)."""
    import jax
    import jax.numpy as jnp

    from eaco_jax.ops.local_search import two_opt

    dist = jnp.asarray(problem.dist, jnp.float32)

    def run():
        return two_opt(tours, dist, problem.neighbors, moves_per_step=per_step, or_opt=or_opt,
                       acceptance=acceptance)

    t0 = time.perf_counter()
    out = jax.block_until_ready(run())
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(run())
        times.append(time.perf_counter() - t0)
    return {"ms_per_call": 1000 * statistics.median(times), "compile_seconds": compile_s}, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["pcb442:1024", "pr1002:384"],
                    help="INSTANCE:ANTS")
    ap.add_argument("--local-search", choices=["2opt", "or-2opt"], default="or-2opt")
    ap.add_argument("--moves-per-step", type=int, default=64,
                    help="moves per step (GraphEACO.ls_moves_per_step's default)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--data-dir", type=Path, action="append")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    import jax
    import jax.numpy as jnp
    import numpy as np

    from eaco_jax.strategies.tour_base import build

    rows = []
    print(f"{'instance':>8} {'ants':>6} {'acceptance':>10} {'ms/call':>8} {'compile s':>9}")
    for case in args.cases:
        name, ants = case.split(":")
        problem = find_instance(name, args.data_dir)
        n = problem.dist.shape[0]
        tours = build(jax.random.key(args.seed), jnp.ones((n, n), jnp.float32), problem,
                      int(ants), jnp.float32(1.0), jnp.float32(2.0))
        got = {}
        for acceptance in ("sequential", "rounds"):
            r, out = time_search(problem, tours, args.local_search == "or-2opt",
                                 args.moves_per_step, acceptance, args.repeats)
            got[acceptance] = (r, np.asarray(out))
            rows.append({"instance": name, "ants": int(ants), "acceptance": acceptance,
                         "local_search": args.local_search,
                         "moves_per_step": args.moves_per_step, **r})
            print(f"{name:>8} {ants:>6} {acceptance:>10} {r['ms_per_call']:8.2f} "
                  f"{r['compile_seconds']:9.1f}", flush=True)
        (seq, seq_tours), (rnd, rnd_tours) = got["sequential"], got["rounds"]
        rows[-1]["same_tours_as_sequential"] = bool(np.array_equal(seq_tours, rnd_tours))
        rows[-1]["speedup"] = seq["ms_per_call"] / rnd["ms_per_call"]
        print(f"{'':>8} speed-up {rows[-1]['speedup']:.2f}x, same tours: "
              f"{rows[-1]['same_tours_as_sequential']}")
    write_results(args.out, rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
