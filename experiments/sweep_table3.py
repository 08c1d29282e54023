"""Paper Table 3 on g01 (G1) as ONE vmapped sweep vs the same cells run one by one.

Table 3 varies (q0, rho, p_c, p_m) over six settings. Here the six settings x ``--seeds`` seeds
run three ways on the same budget (no early stop, so every way does identical work):

* ``batched``: one ``ea.minimize`` call with the list of Params, all settings x seeds vmapped
  (what ``eaco sweep experiments/sweeps/table3_g01.yaml`` does);
* ``per_cell``: one ``minimize`` call per setting, its seeds vmapped (6 runs of one compiled
  program: ``minimize`` caches compiled chunks, so only the first call compiles);
* ``single`` (``--single-runs K``): K single (setting, seed) runs timed, extrapolated to all
  settings x seeds as one compilation + n x the mean run (marked as extrapolated).

The script reports the largest |f batched - f per setting|: 0 on CPU in our runs; on a GPU the
batch size changes how reductions are tiled, so rounding differs and some runs' trajectories
diverge (same distribution, not the same bits). Prints a table and writes
``experiments/results/sweep_table3.json``.

    python experiments/sweep_table3.py                     # 6 settings x 10 seeds
    python experiments/sweep_table3.py --max-evaluations 2000 --seeds 4 --single-runs 1
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402
import numpy as np  # noqa: E402
from table3_g01 import SETTINGS  # noqa: E402  (same folder: the paper's Table 3 rows)

import eaco_jax as ea  # noqa: E402
from eaco_jax import runs  # noqa: E402
from eaco_jax.outputs import write_json  # noqa: E402
from eaco_jax.sweep import with_params  # noqa: E402

RESULTS = Path(__file__).parent / "results" / "sweep_table3.json"
TABLE3 = SETTINGS  # (q0, rho, p_crossover, p_mutation), the rows of the paper's Table 3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--max-evaluations", type=int, default=4000,
                    help="budget per run (iterations = this // num_ants)")
    ap.add_argument("--single-runs", type=int, default=1,
                    help="single (setting, seed) runs to time for the extrapolated baseline")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    kind = runs.get("constrained")  # what `eaco constrained g01` and the sweep file build
    setup = kind.build(kind.make_settings({"problem": "g01",
                                           "max_evaluations": args.max_evaluations}))
    seeds = list(range(args.seeds))
    with setup.context():
        params = [with_params(setup.params, dict(zip(("q0", "rho", "p_crossover", "p_mutation"),
                                                     row, strict=True))) for row in TABLE3]
        # the run kind's budget and chunk length, without its target stop: identical work
        common = {k: v for k, v in setup.budget.items() if k != "target"}
        x64 = bool(jax.config.jax_enable_x64)  # the constrained command runs in float64

        t0 = time.perf_counter()
        batch = ea.minimize(setup.problem, setup.strategy, params=params, seed=seeds, **common)
        jax.block_until_ready(batch.state)
        t_batch = time.perf_counter() - t0

        per_cell, t_cells, compile_cells = [], 0.0, 0.0
        for p in params:
            t0 = time.perf_counter()
            r = ea.minimize(setup.problem, setup.strategy, seed=seeds, params=p, **common)
            t_cells += time.perf_counter() - t0
            compile_cells += r.compile_seconds
            per_cell.append(r)

        t_single, compile_single = [], 0.0
        for k in range(args.single_runs):
            t0 = time.perf_counter()
            r = ea.minimize(setup.problem, setup.strategy, seed=seeds[k % len(seeds)],
                            params=params[k % len(params)], **common)
            t_single.append(time.perf_counter() - t0)
            compile_single += r.compile_seconds

    n = len(TABLE3) * len(seeds)
    shape = (len(TABLE3), len(seeds))
    f_batch = np.asarray(batch.f).reshape(shape)
    f_cells = np.stack([np.asarray(r.f) for r in per_cell]).reshape(shape)
    feas = np.asarray(batch.feasible).reshape(shape)
    agree = float(np.max(np.abs(f_batch - f_cells)))
    # n single runs in one process: the compiled chunk is cached, so one compilation plus n
    # times the mean single run without its compilation
    single_total = (compile_single + (sum(t_single) - compile_single) / len(t_single) * n
                    if t_single else None)

    rows = []
    for i, (q0, rho, pc, pm) in enumerate(TABLE3):
        ok = feas[i] & (f_batch[i] + 15.0 <= 1e-4)
        rows.append({"q0": q0, "rho": rho, "p_crossover": pc, "p_mutation": pm,
                     "mean_f": float(f_batch[i].mean()), "best_f": float(f_batch[i].min()),
                     "std_f": float(f_batch[i].std()), "feasible_rate": float(feas[i].mean()),
                     "success_rate": float(ok.mean())})
    record = {
        "problem": "g01", "settings": len(TABLE3), "seeds": len(seeds), "runs": n,
        "max_evaluations": args.max_evaluations, "iterations": int(batch.iterations),
        "device": str(jax.devices()[0]), "x64": x64,
        "batched_seconds": t_batch, "batched_compile_seconds": batch.compile_seconds,
        "per_cell_seconds": t_cells, "per_cell_compile_seconds": compile_cells,
        "single_run_seconds": t_single, "single_run_compile_seconds": compile_single,
        "single_runs_extrapolated_seconds": single_total,
        "speedup_vs_per_cell": t_cells / t_batch,
        "speedup_vs_single_runs_extrapolated": None if single_total is None
        else single_total / t_batch,
        "max_abs_diff_batched_vs_per_cell": agree,
        "table": rows,
    }
    write_json(args.out, record)
    print(f"g01, Table 3 settings x {len(seeds)} seeds, {args.max_evaluations} evaluations/run")
    print(f"{'q0':>5} {'rho':>5} {'p_c':>5} {'p_m':>5} {'mean f':>12} {'best f':>12} "
          f"{'feasible':>9} {'success':>8}")
    for r in rows:
        print(f"{r['q0']:5.2f} {r['rho']:5.2f} {r['p_crossover']:5.2f} {r['p_mutation']:5.2f} "
              f"{r['mean_f']:12.6f} {r['best_f']:12.6f} {r['feasible_rate']:9.2f} "
              f"{r['success_rate']:8.2f}")
    print(f"\none vmapped call ({n} runs):      {t_batch:8.1f} s "
          f"(compile {batch.compile_seconds:.1f} s)")
    print(f"{len(TABLE3)} calls, one per setting:      {t_cells:8.1f} s "
          f"(compile {compile_cells:.1f} s)  speed-up x{t_cells / t_batch:.2f}")
    if single_total is not None:
        print(f"{n} single runs (extrapolated from {len(t_single)}): {single_total:8.1f} s  "
              f"speed-up x{single_total / t_batch:.2f}")
    print(f"max |f batched - f per setting| = {agree:.3g}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
