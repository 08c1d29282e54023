"""Search a forward gait that stays up while the route walker steers it (issue #32).

    python experiments/walk_steer_search.py --ants 16 --worlds 8 --max-seconds 1800
    python experiments/walk_steer_search.py --backend mjx --ants 256 --worlds 16 ...  # GPU

The problem is :class:`~eaco_jax.problems.gait_steer.SteeredGaitProblem`: every ant walks in
``--worlds`` randomised worlds of the *optimisation* stream (run seed ``--seed``), each world
with its own steering schedule (``--segments`` commands over ``--horizon`` seconds, heading
errors uniform in +/- ``--error-deg`` through the controller's rule); fitness: forward
progress minus a fall cost per fallen world, CVaR over the worlds. The colony searches +/-15 %
of each parameter's range (``--radius``, default ``eaco gait --init``'s box) around the
library's forward gait.

After the search the archive's best ``--finalists`` gaits and the library's forward gait are
walked in ``--check-worlds`` further worlds of the optimisation stream (batches the search's
keys did not pick: indices from 10**6), and ranked by falls, then progress: a preselection
only. The choice between gaits is made by ``experiments/walk_tune.py --gaits`` on the tuning
scenes (selection stream). Writes ``--out``/search.json (device, versions, command, date) and
``--out``/gaits_<k>.json: a gait library (``eaco_jax/data/walk_gaits/nao.json`` with the
forward vector replaced) per finalist, in preselection order.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import sys
import time
from datetime import date
from pathlib import Path

import numpy as np
from common import device_info

from eaco_jax.outputs import write_json
from eaco_jax.runs.gait import INIT_RADIUS

HERE = Path(__file__).resolve().parent
LIBRARY = HERE.parent / "eaco_jax" / "data" / "walk_gaits" / "nao.json"
CHECK_BATCH0 = 10**6


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--backend", default="native", choices=("native", "mjx"))
    ap.add_argument("--impl", default="jax", help="MJX implementation (jax; warp is untried)")
    ap.add_argument("--ants", type=int, default=16)
    ap.add_argument("--worlds", type=int, default=8)
    ap.add_argument("--aggregate", default="cvar", choices=("cvar", "worst", "mean"))
    ap.add_argument("--latency", type=int, default=None, help="worlds' latency bound "
                    "(control steps; default RobustConfig's): harsher worlds fall more often")
    ap.add_argument("--target-noise", type=float, default=None, help="worlds' target noise "
                    "(rad; default RobustConfig's)")
    ap.add_argument("--horizon", type=float, default=12.0)
    ap.add_argument("--segments", type=int, default=6)
    ap.add_argument("--error-deg", type=float, default=75.0)
    ap.add_argument("--radius", type=float, default=INIT_RADIUS,
                    help="search box: +/- this fraction of each range around the library gait")
    ap.add_argument("--iterations", type=int, default=10_000)
    ap.add_argument("--max-seconds", type=float, default=1800.0)
    ap.add_argument("--seed", type=int, default=0, help="run seed: colony and world streams")
    ap.add_argument("--finalists", type=int, default=4)
    ap.add_argument("--check-worlds", type=int, default=64)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "walk" / "steer_search")
    args = ap.parse_args()
    import jax
    import jax.numpy as jnp

    import eaco_jax as ea
    from eaco_jax.gait.worlds import RobustConfig, stream_key
    from eaco_jax.problems.gait_steer import SteerConfig, make_steered_problem
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO

    library = json.loads(LIBRARY.read_text())
    init = np.asarray(library["gaits"]["forward"]["vector"], np.float32)
    steer = SteerConfig(segments=args.segments, error_deg=args.error_deg)
    harsh = {k: v for k, v in (("latency", args.latency), ("target_noise", args.target_noise))
             if v is not None}
    robust = RobustConfig(R=args.worlds, aggregate=args.aggregate, seed=args.seed, **harsh)
    problem = make_steered_problem("nao", backend=args.backend, impl=args.impl,
                                   horizon=args.horizon, robust=robust, steer=steer)
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    half = args.radius * (hi - lo)
    search = problem.replace(lower=jnp.asarray(np.maximum(lo, init - half), jnp.float32),
                             upper=jnp.asarray(np.minimum(hi, init + half), jnp.float32))
    strategy = ContinuousEACO(num_ants=args.ants, archive_size=max(2, (3 * args.ants) // 2),
                              refine_ants=0, repair_steps=0)
    t0 = time.perf_counter()
    result = ea.minimize(search, strategy, seed=args.seed, iterations=args.iterations,
                         max_seconds=args.max_seconds, chunk_size=1)
    search_s = time.perf_counter() - t0
    archive = np.asarray(result.state.archive_x, np.float32).reshape(-1, init.size)
    cands = np.concatenate([init[None], archive[: args.finalists]])
    cands = np.clip(cands, np.asarray(search.lower), np.asarray(search.upper))
    cands[0] = init  # the library's gait as it is (it may sit outside the narrowed box)
    # the preselection walks in the worlds the walker meets (the default ranges)
    check = problem.replace(robust=RobustConfig(R=args.check_worlds, seed=args.seed))
    run = jax.jit(lambda x, k: check.rollout(x, check.worlds(k)))
    out = jax.tree.map(np.asarray, run(jnp.asarray(cands),
                                       stream_key(args.seed, "optimisation", CHECK_BATCH0)))
    falls = out["fell"].sum(axis=1)
    progress = out["distance_m"].mean(axis=1)
    order = np.lexsort((-progress, falls))
    rows = [{"candidate": "library forward" if i == 0 else f"archive {i - 1}",
             "falls": int(falls[i]), "worlds": args.check_worlds,
             "progress_m_mean": float(progress[i]), "vector": cands[i].tolist()}
            for i in range(len(cands))]
    args.out.mkdir(parents=True, exist_ok=True)
    for rank, i in enumerate(order):
        lib = copy.deepcopy(library)
        lib["gaits"]["forward"] = {"vector": cands[i].tolist(),
                                   "from": f"experiments/walk_steer_search.py "
                                   f"({rows[i]['candidate']})"}
        rows[i]["library_file"] = str(args.out / f"gaits_{rank}.json")
        write_json(args.out / f"gaits_{rank}.json", lib)
    best = (result.history or {}).get("best_cost")
    record = {
        "command": "python experiments/walk_steer_search.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "device": device_info(),
        "seeds": {"run": args.seed, "search_worlds": "optimisation stream (driver keys)",
                  "check_worlds": f"optimisation stream batch {CHECK_BATCH0}"},
        "settings": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "steer": dataclasses.asdict(steer),
        "search_seconds": search_s, "iterations": int(result.iterations),
        "evaluations": int(np.asarray(result.evaluations).reshape(-1)[0]),
        "best_fitness": -float(np.asarray(result.best_cost).reshape(-1)[0]),
        "history_best_fitness": (None if best is None else
                                 (-np.asarray(best, np.float64).reshape(-1)).tolist()),
        "preselection_order": [int(i) for i in order], "candidates": rows}
    write_json(args.out / "search.json", record)
    for rank, i in enumerate(order):
        print(rank, rows[i]["candidate"], "falls", rows[i]["falls"], "/", args.check_worlds,
              "progress", round(rows[i]["progress_m_mean"], 3), flush=True)


if __name__ == "__main__":
    main()
