"""CEC2006 protocol for continuous EACO on g01, g09, g10, g13 (the paper's G1, G3, G2, G4),
in two modes and three accountings.

25 independent runs per problem (seeds vmapped in one compiled call), at most 500,000
evaluations, success = feasible and f - f* <= 1e-4 (Liang et al. 2006). Success performance
SP = mean(evaluations of successful runs) * runs / successes, beside the published epsilon-DE
figures (Takahama & Sakai, CEC 2006) and the best SP per problem among the CEC2006 entries.

Modes:
* ``derivative-free`` (``repair_steps=0, refine_ants=0``): every evaluation is a point of the
  colony. This is the mode to compare with derivative-free methods.
* ``gradient`` (the defaults: gradient repair and SQP refinement with autodiff derivatives).
  Accountings: "charged" (the library's count: a repair step 1, a refinement n + 1),
  "FD" (finite differences, one evaluation = objective and all constraints at a point: a repair
  step n + 1, a refinement's Hessian (n + 1)(n + 2)/2) and "FD per function" (every function
  apart: n + 1 per gradient per constraint, (n + 1)(n + 2)/2 per Hessian per function); see
  ``eaco_jax.strategies.continuous_eaco``. Note that epsilon-DE's CEC2006 entry itself uses a
  gradient-based mutation on the constraints (the title of the paper says so).

    python experiments/cec2006.py                                 # both modes, 25 runs
    python experiments/cec2006.py --runs 4 --problems g13 --modes gradient
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import jax
import numpy as np

import eaco_jax as ea
from eaco_jax.problems import cec2006, float64
from eaco_jax.strategies.continuous_eaco import ContinuousEACO

EPS_DE_SP = {"g01": 59_308, "g09": 23_121, "g10": 105_234, "g13": 34_738}
BEST_SP = {"g01": 25_115, "g09": 16_152, "g10": 25_520, "g13": 21_732}
PAPER_NAME = {"g01": "G1", "g10": "G2", "g09": "G3", "g13": "G4"}
RESULTS = Path(__file__).parent / "results"
MODES = {"derivative-free": dict(repair_steps=0, refine_ants=0), "gradient": {}}
COUNTS = {"charged": "target_evaluations", "fd": "target_fd_evaluations",
          "fd_per_function": "target_fd_function_evaluations"}


def sp(te: np.ndarray) -> float | None:
    ok = te >= 0
    return float(te[ok].mean() * te.size / ok.sum()) if ok.any() else None


def run_problem(name: str, mode: str, runs: int, budget: int, chunk: int, method: str) -> dict:
    """All ``runs`` seeds of one problem as one vmapped call, until all hit or the budget."""
    prob = cec2006(name)
    strategy = ContinuousEACO(constraint_method=method, **MODES[mode])
    iterations = budget // strategy.num_ants

    def all_hit(state, progress) -> bool:
        ev = np.asarray(state.evaluations)
        return bool(np.all(np.asarray(state.target_evaluations) >= 0) or np.all(ev >= budget))

    res = ea.minimize(prob, strategy, seed=list(range(runs)), iterations=iterations,
                      chunk_size=chunk, stop=all_hit)
    s = res.state
    targets = {k: np.asarray(getattr(s, v)) for k, v in COUNTS.items()}
    # a run succeeds within the budget of *charged* evaluations (the budget the run had)
    ok = (targets["charged"] >= 0) & (targets["charged"] <= budget)
    targets = {k: np.where(ok, v, -1) for k, v in targets.items()}
    err = np.asarray(s.best_f) - prob.f_star
    viol = np.asarray(s.best_violation)
    row = {
        "problem": name, "paper_name": PAPER_NAME[name], "mode": mode, "f_star": prob.f_star,
        "runs": runs, "successes": int(ok.sum()), "success_rate": float(ok.mean()),
        **{f"sp_{k}": sp(v) for k, v in targets.items()},
        **{f"success_within_budget_{k}": float(np.mean((v >= 0) & (v <= budget)))
           for k, v in targets.items()},
        "eps_de_sp": EPS_DE_SP[name], "best_cec2006_sp": BEST_SP[name],
        **{f"evaluations_to_target_{k}": [int(t) if t >= 0 else None for t in v]
           for k, v in targets.items()},
        "best_error_at_stop": [float(e) for e in err],
        "violation_at_stop": [float(v) for v in viol],
        "all_feasible": bool(np.all(viol <= 0)),
        "compile_seconds": res.compile_seconds,
        "run_seconds": res.seconds - res.compile_seconds,
        "iterations": res.iterations, "method": method,
    }
    return row


def fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:,.0f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=25)
    ap.add_argument("--problems", default="g01,g09,g10,g13")
    ap.add_argument("--modes", default="derivative-free,gradient")
    ap.add_argument("--budget", type=int, default=500_000)
    ap.add_argument("--chunk", type=int, default=250, help="iterations per compiled call")
    ap.add_argument("--method", default="epsilon", choices=["epsilon", "deb", "penalty"])
    ap.add_argument("--out", default=str(RESULTS / "cec2006"), help="path stem for .json/.csv")
    args = ap.parse_args()

    rows = []
    with float64():
        for mode in args.modes.split(","):
            for name in args.problems.split(","):
                row = run_problem(name.strip(), mode, args.runs, args.budget, args.chunk,
                                  args.method)
                rows.append(row)
                print(f"  {mode} {name}: {row['successes']}/{row['runs']} in "
                      f"{row['run_seconds']:.1f}s (+{row['compile_seconds']:.1f}s compile)",
                      flush=True)

    header = (f"{'problem':7} {'mode':16} {'success':>7} {'SP charged':>11} {'SP FD':>11} "
              f"{'SP FD/func':>11} {'eps-DE SP':>10} {'best SP':>8}")
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{r['problem']:7} {r['mode']:16} {r['successes']:>3}/{r['runs']:<3} "
              f"{fmt(r['sp_charged']):>11} {fmt(r['sp_fd']):>11} "
              f"{fmt(r['sp_fd_per_function']):>11} {r['eps_de_sp']:>10,} "
              f"{r['best_cec2006_sp']:>8,}")
    stem = Path(args.out)
    stem.parent.mkdir(parents=True, exist_ok=True)
    meta = {"budget": args.budget, "runs": args.runs, "method": args.method,
            "device": str(jax.devices()[0]), "jax": jax.__version__,
            "success": "feasible and f - f* <= 1e-4 within the budget of charged evaluations"}
    stem.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=2)
                                         + "\n")
    keys = ["problem", "paper_name", "mode", "f_star", "runs", "successes", "success_rate",
            "sp_charged", "sp_fd", "sp_fd_per_function", "success_within_budget_fd",
            "success_within_budget_fd_per_function", "eps_de_sp", "best_cec2006_sp",
            "all_feasible", "compile_seconds", "run_seconds", "iterations", "method"]
    with stem.with_suffix(".csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in keys})
    print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.csv')}")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"{time.perf_counter() - t0:.0f} s")
