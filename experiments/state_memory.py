"""Memory of a vmapped colony: bytes held per seed row, and the compiled chunk's buffers.

Issue 11: a 16-seed run of a 1,002-city TSP used to hold 16 copies of the problem's data
(distance matrix, heuristic cache, candidate lists) inside the colony state. Now the problem
is passed to ask/tell and held once. Prints a table and writes JSON; run it on two commits to
compare (``--label``). The instance is 1,002 random cities in a 10,000 x 10,000 square (same
size as pr1002; the coordinates do not matter for memory).

    python experiments/state_memory.py --out experiments/results/state_memory.json
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
from pathlib import Path

import jax
import numpy as np

import eaco_jax as ea


def tree_bytes(tree) -> int:
    return int(sum(np.asarray(x).nbytes if not jax.dtypes.issubdtype(
        getattr(x, "dtype", np.float32), jax.dtypes.prng_key) else 8 * np.size(x)
        for x in jax.tree.leaves(tree)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1002)
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--ants", type=int, default=32)
    ap.add_argument("--label", default=None, help="name of this row (default: git commit)")
    ap.add_argument("--out", type=Path, default=None, help="append the row to this JSON file")
    args = ap.parse_args()
    from eaco_jax.problems import TSP
    from eaco_jax.strategies import GraphEACO

    rng = np.random.default_rng(0)
    tsp = TSP.from_coords(rng.uniform(0, 10_000, (args.n, 2)), name=f"random{args.n}")
    strategy = GraphEACO(num_ants=args.ants, local_search="none")
    res = ea.minimize(tsp, strategy, seed=list(range(args.seeds)), iterations=2, chunk_size=1)
    state_bytes = tree_bytes(res.state)
    problem_bytes = tree_bytes(tsp)
    matrix = args.n * args.n * 4
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    row = {
        "label": args.label or commit, "commit": commit, "n": args.n, "seeds": args.seeds,
        "ants": args.ants, "state_bytes": state_bytes,
        "state_bytes_per_seed": state_bytes // args.seeds,
        "n_by_n_matrices_per_seed": round(state_bytes / args.seeds / matrix, 2),
        "problem_bytes": problem_bytes, "jax": jax.__version__,
        "device": str(jax.devices()[0]), "host": platform.node(),
    }
    print(f"{'label':>10} {'state MB':>9} {'per seed MB':>12} {'n x n per seed':>15} "
          f"{'problem MB':>11}")
    print(f"{row['label']:>10} {state_bytes / 1e6:9.1f} {state_bytes / args.seeds / 1e6:12.2f} "
          f"{row['n_by_n_matrices_per_seed']:15.2f} {problem_bytes / 1e6:11.1f}")
    if args.out is not None:
        rows = json.loads(args.out.read_text())["rows"] if args.out.exists() else []
        rows = [r for r in rows if r["label"] != row["label"]] + [row]
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
