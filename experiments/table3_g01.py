"""The paper's Table 3 on G1 (= CEC2006 g01): sensitivity to (q0, rho, p_c, p_m).

All settings x seeds run as ONE vmapped, jitted sweep (vmap over stacked ContinuousParams,
vmap over seeds, lax.scan over iterations) - no Python loop over settings or seeds. Reports,
per setting, the success rate, the mean iterations to target (feasible f - f* <= 1e-4) of the
successful runs, and the mean / best final value. The sixth row (0.8, 0.3, 0.5, 0.6) is the
text's reading of the best setting (the table says 0.6, 0.5; PAPER_NOTES.md section 1).

    python experiments/table3_g01.py --seeds 10 --iterations 300
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.driver.minimize import iteration_step
from eaco_jax.problems import cec2006, float64
from eaco_jax.strategies.continuous_eaco import ContinuousEACO, ContinuousParams

SETTINGS = [  # (q0, rho, p_crossover, p_mutation)
    (0.2, 0.1, 0.2, 0.2),
    (0.4, 0.2, 0.3, 0.3),
    (0.6, 0.3, 0.4, 0.4),
    (0.8, 0.3, 0.6, 0.5),
    (0.9, 0.4, 0.8, 0.8),
    (0.8, 0.3, 0.5, 0.6),
]
RESULTS = Path(__file__).parent / "results"


def sweep(problem, strategy, params, seeds: int, iterations: int):
    """Final states of every (setting, seed): one jitted call."""

    def one(p, key):
        state = strategy.init(key, problem, p)

        def body(s, _):
            s, _ = iteration_step(strategy, problem, s)
            return s, None

        state, _ = jax.lax.scan(body, state, None, length=iterations)
        return state

    keys = jnp.stack([jax.random.key(s) for s in range(seeds)])
    run = jax.jit(jax.vmap(jax.vmap(one, in_axes=(None, 0)), in_axes=(0, None)))
    return run(params, keys)


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
        params = jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *sets)
        assert isinstance(params, ContinuousParams)
        t0 = time.perf_counter()
        states = sweep(prob, strategy, params, args.seeds, args.iterations)
        jax.block_until_ready(states)
        seconds = time.perf_counter() - t0

    it = np.asarray(states.target_iteration)  # (settings, seeds), -1 if never
    ev = np.asarray(states.target_evaluations)
    best = np.asarray(states.best_f)
    feas = np.asarray(states.best_violation) <= 0
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
          f"iterations, one jitted sweep: {seconds:.1f}s (incl. compile)")
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
            "device": str(jax.devices()[0])}
    stem.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=2) + "\n")
    with stem.with_suffix(".csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.csv')}")


if __name__ == "__main__":
    main()
