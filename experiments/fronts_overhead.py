"""Where the colony arm of ``gait_fronts.py`` spends its time beyond the physics: the same
seeds, ants and generations run (a) as ``ea.minimize`` with ``MOEACO`` (ask, evaluate, tell and
the metrics in one compiled chunk, seeds vmapped) and (b) as the bare evaluation, the jitted
``vmap(problem.evaluate)`` called once per generation as the NSGA-II arm calls it.

Session 27's Warp fronts run took 201 s for the colony against 108 s for NSGA-II at equal
evaluations; this script measures the overhead on any backend, so the Warp case can be timed
beside the CPU ones. ``--graph-mode`` picks MuJoCo Warp's CUDA graph mode: MJX's default
(``warp``) replays a captured graph only for the buffer addresses it was captured with, which a
call inside ``minimize``'s compiled loop may not keep; ``warp_staged`` copies through fixed
staging buffers instead.

    python experiments/fronts_overhead.py --backend native --ants 16 --generations 6 --seeds 4
    python experiments/fronts_overhead.py --backend mjx --impl warp --ants 128 --worlds 4 \\
        --generations 4 --seeds 10 --horizon 20 [--graph-mode warp_staged]   # a GPU

Writes ``results/gait_fronts/overhead_<backend>_<impl>.json``.
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from pathlib import Path

import common as st
import jax
import jax.numpy as jnp
from gait_fronts import seeds_evaluate

import eaco_jax as ea
from eaco_jax.gait.rollout_mjx import WARP_GRAPH_MODES
from eaco_jax.problems.gait_mo import make_gait_mo_problem
from eaco_jax.runs.gait import narrowed_around, steering_of, world_ranges
from eaco_jax.strategies import MOEACO

RESULTS = Path(__file__).resolve().parent / "results" / "gait_fronts"
FLAT = (Path(__file__).resolve().parent / "results" / "nao_constrained_warp" / "flat_r32"
        / "best_gait.json")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--backend", default="native", choices=("native", "mjx"))
    ap.add_argument("--impl", default="jax", choices=("jax", "warp"))
    ap.add_argument("--ants", type=int, default=16)
    ap.add_argument("--worlds", type=int, default=1)
    ap.add_argument("--generations", type=int, default=6)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--horizon", type=float, default=1.0)
    ap.add_argument("--graph-mode", default=None, choices=WARP_GRAPH_MODES,
                    help="MuJoCo Warp's CUDA graph mode (EACO_WARP_GRAPH_MODE; default MJX's: "
                    "warp, which replays a graph only for the buffer addresses it captured)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    if args.graph_mode is not None:
        os.environ["EACO_WARP_GRAPH_MODE"] = args.graph_mode
    robust = world_ranges(0, 0.000443, R=args.worlds, resample=True)
    problem = make_gait_mo_problem("nao", "endurance", backend=args.backend, impl=args.impl,
                                   horizon=args.horizon, robust=robust,
                                   steering=steering_of(True))
    problem, _ = narrowed_around(problem, FLAT)
    seeds = list(range(args.seeds))

    t0 = time.perf_counter()
    res = ea.minimize(problem, strategy=MOEACO(num_ants=args.ants, archive_size=args.ants),
                      seed=seeds, iterations=args.generations)
    colony = {"wall_s": time.perf_counter() - t0, "compile_s": res.compile_seconds,
              "run_s": res.seconds - res.compile_seconds}

    evaluate = seeds_evaluate(problem, len(seeds))
    x = jnp.broadcast_to((problem.lower + problem.upper) / 2,
                         (len(seeds), args.ants, problem.dim))
    keys = jax.vmap(jax.random.PRNGKey)(jnp.asarray(seeds))
    t0 = time.perf_counter()
    jax.block_until_ready(evaluate(x, keys))
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for g in range(args.generations):
        keys = jax.vmap(lambda k, g=g: jax.random.fold_in(k, g))(keys)
        jax.block_until_ready(evaluate(x, keys))
    bare = {"compile_s": compile_s, "run_s": time.perf_counter() - t0}
    ratio = colony["run_s"] / bare["run_s"]
    print(f"colony run {colony['run_s']:.2f} s (compile {colony['compile_s']:.1f}), bare "
          f"evaluation {bare['run_s']:.2f} s (compile {bare['compile_s']:.1f}): x{ratio:.2f}")
    mode = f"_{args.graph_mode}" if args.graph_mode else ""
    out = args.out or RESULTS / f"overhead_{args.backend}_{args.impl}{mode}.json"
    st.write_results(out, [{"arm": "colony (minimize)", **colony},
                           {"arm": "bare evaluation", **bare}],
                     ratio_run=ratio, date=datetime.date.today().isoformat(),
                     command="python experiments/fronts_overhead.py " + " ".join(sys.argv[1:]),
                     settings=vars(args) | {"out": str(out)},
                     versions={"eaco_jax": ea.__version__, "jax": jax.__version__})


if __name__ == "__main__":
    main()
