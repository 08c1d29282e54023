"""SHA-256 of the tours a colony builds, to check that a change leaves them bit-identical.

Runs ``GraphEACO`` through its own ``init`` / ``ask`` / ``tell`` for a few iterations per
(instance, local search, seed) and hashes every iteration's tours and the final best tour.
Run it before and after a change to construction or local search and compare the printed
hashes (``--out`` writes them as JSON; ``--check FILE`` compares with an earlier output and
exits 1 on any difference).

    python experiments/tour_hashes.py --out /tmp/before.json
    python experiments/tour_hashes.py --check /tmp/before.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path


def colony_hash(name: str, local_search: str, seed: int, iterations: int, ants: int,
                candidate_lists: bool = True) -> str:
    """Hash of all tours of ``iterations`` iterations of one seeded colony."""
    import jax
    import numpy as np

    from eaco_jax.problems import load_tsplib
    from eaco_jax.strategies.graph_eaco import GraphEACO

    problem = load_tsplib(name)
    strategy = GraphEACO(num_ants=ants, local_search=local_search,
                         candidate_lists=candidate_lists)
    params = strategy.default_params(problem)
    key, k_init = jax.random.split(jax.random.key(seed))
    state = strategy.init(k_init, problem, params)
    h = hashlib.sha256()
    for _ in range(iterations):
        key, k_ask = jax.random.split(key)
        tours, state = strategy.ask(k_ask, state, problem)
        h.update(np.asarray(tours, np.int32).tobytes())
        state, _ = strategy.tell(state, tours, problem.evaluate(tours), problem)
    h.update(np.asarray(state.best_solution, np.int32).tobytes())
    return h.hexdigest()[:16]


CASES = [(inst, ls, cl) for inst in ("eil51", "kroA100") for ls in ("none", "2opt")
         for cl in (True, False)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--iterations", type=int, default=5)
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--check", type=Path)
    args = ap.parse_args()
    hashes = {}
    for inst, ls, cl in CASES:
        for seed in range(args.seeds):
            key = f"{inst}/{ls}/{'cand' if cl else 'full'}/seed{seed}"
            hashes[key] = colony_hash(inst, ls, seed, args.iterations, args.ants, cl)
            print(f"{key:32s} {hashes[key]}", flush=True)
    if args.out:
        args.out.write_text(json.dumps(hashes, indent=1) + "\n")
    if args.check:
        old = json.loads(args.check.read_text())
        bad = [k for k in hashes if old.get(k) != hashes[k]]
        print("IDENTICAL" if not bad else f"DIFFERENT: {bad}")
        sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
