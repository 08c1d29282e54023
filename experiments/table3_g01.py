"""The paper's Table 3 on G1 (= CEC2006 g01): sensitivity to (q0, rho, p_c, p_m).

All settings x seeds run as ONE vmapped, jitted call (``ea.minimize`` with a list of
ContinuousParams and a list of seeds: vmap over settings x seeds, lax.scan over iterations) - no
Python loop over settings or seeds. Reports, per setting, the success rate, the mean iterations
to target (feasible f - f* <= 1e-4) of the successful runs, and the mean / best final value.
The sixth row (0.8, 0.3, 0.5, 0.6) is the text's reading of the best setting (the table says
0.6, 0.5; PAPER_NOTES.md section 1).

    python experiments/table3_g01.py --seeds 10 --iterations 300
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import jax
import numpy as np

import eaco_jax as ea
from eaco_jax.problems import cec2006, float64
from eaco_jax.strategies.continuous_eaco import ContinuousEACO

SETTINGS = [  # (q0, rho, p_crossover, p_mutation)
    (0.2, 0.1, 0.2, 0.2),
    (0.4, 0.2, 0.3, 0.3),
    (0.6, 0.3, 0.4, 0.4),
    (0.8, 0.3, 0.6, 0.5),
    (0.9, 0.4, 0.8, 0.8),
    (0.8, 0.3, 0.5, 0.6),
]
RESULTS = Path(__file__).parent / "results"


def sweep(problem, strategy, params, seeds: int, iterations: int) -> ea.Result:
    """Every (setting, seed) as one vmapped run; row r is setting r // seeds, seed r % seeds.

    One chunk of ``iterations``: a single compiled call, no stop rule (each row records the
    iteration / evaluation count at which it first met the target in its state).
    """
    return ea.minimize(problem, strategy, seed=list(range(seeds)), params=list(params),
                       iterations=iterations, chunk_size=iterations)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--iterations", type=int, default=300)
    ap.add_argument("--out", default=str(RESULTS / "table3_g01"))
    args = ap.parse_args()

    with float64():
        prob = cec2006("g01")
        strategy = ContinuousEACO()
        base = strategy.default_params(prob)
        sets = [base.replace(q0=q0, rho=rho, p_crossover=pc, p_mutation=pm)
                for q0, rho, pc, pm in SETTINGS]
        res = sweep(prob, strategy, sets, args.seeds, args.iterations)
        seconds = res.seconds

    shape = (len(SETTINGS), args.seeds)
    states = res.state
    it = np.asarray(states.target_iteration).reshape(shape)  # -1 if never
    ev = np.asarray(states.target_evaluations).reshape(shape)
    best = np.asarray(states.best_f).reshape(shape)
    feas = np.asarray(states.best_violation).reshape(shape) <= 0
    rows = []
    for i, (q0, rho, pc, pm) in enumerate(SETTINGS):
        ok = it[i] >= 0
        rows.append({
            "q0": q0, "rho": rho, "p_crossover": pc, "p_mutation": pm,
            "seeds": args.seeds, "iterations_budget": args.iterations,
            "success_rate": float(ok.mean()),
            "mean_iterations_to_target": float(it[i][ok].mean()) if ok.any() else None,
            "mean_evaluations_to_target": float(ev[i][ok].mean()) if ok.any() else None,
            "mean_best_f": float(np.where(feas[i], best[i], np.nan).mean()),
            "best_f": float(np.where(feas[i], best[i], np.inf).min()),
            "all_feasible": bool(feas[i].all()),
        })
    print(f"g01 (f* = -15), {args.seeds} seeds x {len(SETTINGS)} settings, {args.iterations} "
          f"iterations, one jitted sweep: {seconds:.1f}s "
          f"(incl. {res.compile_seconds:.1f}s compile)")
    print(f"{'q0':>4} {'rho':>4} {'p_c':>4} {'p_m':>4} {'success':>8} {'iters':>8} "
          f"{'evals':>8} {'mean f':>12} {'best f':>12}")
    for r in rows:
        its = "-" if r["mean_iterations_to_target"] is None else \
            f"{r['mean_iterations_to_target']:.1f}"
        evs = "-" if r["mean_evaluations_to_target"] is None else \
            f"{r['mean_evaluations_to_target']:.0f}"
        print(f"{r['q0']:>4} {r['rho']:>4} {r['p_crossover']:>4} {r['p_mutation']:>4} "
              f"{r['success_rate']:>8.2f} {its:>8} {evs:>8} {r['mean_best_f']:>12.6f} "
              f"{r['best_f']:>12.6f}")
    stem = Path(args.out)
    stem.parent.mkdir(parents=True, exist_ok=True)
    meta = {"seeds": args.seeds, "iterations": args.iterations, "seconds": seconds,
            "compile_seconds": res.compile_seconds, "device": str(jax.devices()[0])}
    stem.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=2) + "\n")
    with stem.with_suffix(".csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.csv')}")


if __name__ == "__main__":
    main()
