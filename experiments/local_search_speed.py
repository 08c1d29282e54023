"""How fast is the colony 2-opt pass? (eaco_jax.ops.local_search.two_opt)

For each instance: a colony of ``--ants`` tours, either "rnn" (randomised nearest neighbour:
from a random start, the nearest unvisited city, the second nearest with probability 0.1 -
roughly what ants with beta = 5 build) or "random" permutations, is improved by one call of
``two_opt`` with the instance's candidate lists. Prints a table (wall ms per colony pass,
median of ``--repeats`` after one compile run; moves per ant; tour gap to the optimum before and
after; mean gain %) and writes ``experiments/results/local_search_speed.json``.

    python experiments/local_search_speed.py --instances eil51 kroA100 a280 pcb442 --ants 40
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.ops.local_search import two_opt
from eaco_jax.problems import load_tsplib

RESULTS = Path(__file__).resolve().parent / "results" / "local_search_speed.json"


def randomised_nn(key: jax.Array, dist: jax.Array, eps: float = 0.1) -> jax.Array:
    """Nearest-neighbour tour from a random start; with probability eps the 2nd nearest."""
    n = dist.shape[0]
    k_start, k_u = jax.random.split(key)
    start = jax.random.randint(k_start, (), 0, n)
    u = jax.random.uniform(k_u, (n,))

    def step(i, carry):
        tour, visited = carry
        d = jnp.where(visited, jnp.inf, dist[tour[i - 1]])
        first = jnp.argmin(d)
        d2 = d.at[first].set(jnp.inf)
        second = jnp.argmin(d2)
        nxt = jnp.where((u[i] < eps) & jnp.isfinite(d2[second]), second, first).astype(jnp.int32)
        return tour.at[i].set(nxt), visited.at[nxt].set(True)

    tour = jnp.zeros(n, jnp.int32).at[0].set(start)
    visited = jnp.zeros(n, bool).at[start].set(True)
    return jax.lax.fori_loop(1, n, step, (tour, visited))[0]


def measure(name: str, ants: int, start: str, repeats: int, k: int, per_step: int, seed: int):
    problem = load_tsplib(name, neighbors=k)
    key = jax.random.key(seed)
    if start == "rnn":
        keys = jax.random.split(key, ants)
        tours = jax.jit(jax.vmap(randomised_nn, (0, None)))(keys, problem.dist)
    else:
        keys = jax.random.split(key, ants)
        tours = jax.vmap(lambda kk: jax.random.permutation(kk, problem.n))(keys).astype(jnp.int32)
    fn = jax.jit(
        lambda t: two_opt(
            t, problem.dist, problem.neighbors, return_moves=True, moves_per_step=per_step
        )
    )
    t0 = time.perf_counter()
    out, moves = fn(tours)
    out.block_until_ready()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out, moves = fn(tours)
        out.block_until_ready()
        times.append(time.perf_counter() - t0)
    before = np.asarray(problem.evaluate(tours), np.float64)
    after = np.asarray(problem.evaluate(out), np.float64)
    return {
        "instance": name,
        "n": problem.n,
        "ants": ants,
        "start": start,
        "neighbors": int(problem.neighbors.shape[1]),
        "moves_per_step": per_step,
        "ms_per_pass": 1e3 * float(np.median(times)),
        "ms_per_pass_min": 1e3 * float(np.min(times)),
        "compile_and_first_s": first,
        "moves_mean": float(np.mean(moves)),
        "moves_max": int(np.max(moves)),
        "gap_before_pct": 100 * (before.mean() / problem.optimum - 1),
        "gap_after_pct": 100 * (after.mean() / problem.optimum - 1),
        "best_gap_after_pct": 100 * (after.min() / problem.optimum - 1),
        "mean_gain_pct": 100 * float(np.mean(1 - after / before)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--instances", nargs="+", default=["eil51", "kroA100", "a280", "pcb442"])
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--starts", nargs="+", default=["rnn", "random"], choices=["rnn", "random"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--neighbors", type=int, default=20)
    ap.add_argument("--moves-per-step", type=int, nargs="+", default=[32])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    rows = []
    header = (
        f"{'instance':>9} {'ants':>4} {'start':>6} {'mps':>3} {'ms/pass':>8} "
        f"{'moves':>12} {'gap0 %':>8} {'gap1 %':>7} {'best %':>7} {'gain %':>7}"
    )
    print(header)
    for name in args.instances:
        for start in args.starts:
            for per_step in args.moves_per_step:
                r = measure(
                    name, args.ants, start, args.repeats, args.neighbors, per_step, args.seed
                )
                rows.append(r)
                print(
                    f"{name:>9} {r['ants']:>4} {start:>6} {per_step:>3} "
                    f"{r['ms_per_pass']:>8.1f} {r['moves_mean']:>6.1f}/{r['moves_max']:<5d} "
                    f"{r['gap_before_pct']:>8.1f} {r['gap_after_pct']:>7.2f} "
                    f"{r['best_gap_after_pct']:>7.2f} {r['mean_gain_pct']:>7.2f}",
                    flush=True,
                )
    record = {
        "experiment": "local_search_speed",
        "what": "one two_opt call on a colony; wall ms per pass (median over repeats)",
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "jax": jax.__version__,
            "backend": jax.default_backend(),
            "load_average": os.getloadavg(),
        },
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
