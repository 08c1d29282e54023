"""Optimise a NAO walking gait with the continuous EACO colony, then verify it on both backends.

The colony searches the walk engine's parameters (``eaco_jax.gait.walk_engine``) on a short
horizon (cheap), then the best gait is re-simulated for ``--verify-horizon`` seconds (the
paper's 20 s) on the native and the MJX backend. ``--around PARAMS.json --radius R`` restricts
the search box to ``R`` x (box width) around a stored gait (a second, local stage).

``--robust R`` scores every ant in R randomised worlds (``RobustConfig``: friction, masses,
motors, target noise and latency, initial pose, a push), aggregated by ``--aggregate`` (cvar,
worst or mean); the search draws fresh worlds every iteration from ``--world-seed``'s stream
(fixed worlds overfit them). ``--penalty cot|power --penalty-weight W`` makes the fitness
energy-aware.
``--trials N`` then replays the best gait in N fresh randomised worlds (a key stream disjoint
from the search's) on every verified backend, and ``--accurate-trials`` once more on native
MuJoCo with its default solver settings.

Example (CPU, ~10 min on 2 cores)::

    python experiments/optimize_nao_gait.py --ants 16 --iterations 40 --horizon 6 --robust 8 \
        --trials 100 --out experiments/results/nao_robust_gait.json

GPU (the lead's; MJX)::

    python experiments/optimize_nao_gait.py --backend mjx --ants 4096 --archive 6144 \
        --iterations 30 --horizon 10 --robust 16 --trials 100 --verify-backends mjx,native

Prints progress and a table; writes JSON with the parameters (by name and as a vector), the
measured ``speed_mps``, ``distance_m``, ``fell``, ``drift_deg`` and energy / gait-quality
metrics on each verified backend, and the trials.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("JAX_PLATFORMS", "cpu")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import eaco_jax as ea  # noqa: E402
from eaco_jax.gait.validate import evaluate_trials  # noqa: E402
from eaco_jax.gait.worlds import RobustConfig  # noqa: E402
from eaco_jax.problems.gait import make_gait_problem  # noqa: E402
from eaco_jax.strategies.continuous_eaco import ContinuousEACO  # noqa: E402

KEYS = ("speed_mps", "distance_m", "fell", "drift_deg", "fitness", "fall_time")


def run_info(problem) -> dict:
    """Device and versions for the stored JSON."""
    import importlib.metadata as md
    import sys

    def version(name: str) -> str | None:
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return None

    dev = jax.devices()[0]
    return {"device": getattr(dev, "device_kind", str(dev)), "platform": dev.platform,
            "mjx_impl": problem.impl if problem.backend == "mjx" else None,
            "python": sys.version.split()[0],
            **{k: version(k) for k in ("jax", "mujoco", "mujoco-mjx", "warp-lang")},
            "argv": sys.argv[1:]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="nao")
    ap.add_argument("--ants", type=int, default=16)
    ap.add_argument("--archive", type=int, default=24)
    ap.add_argument("--iterations", type=int, default=60)
    ap.add_argument("--backend", default="native", choices=["native", "mjx", "auto"])
    ap.add_argument("--slope", type=float, default=0.0)
    ap.add_argument("--direction", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--horizon", type=float, default=6.0, help="optimisation horizon [s]")
    ap.add_argument("--verify-horizon", type=float, default=20.0)
    ap.add_argument("--verify-backends", default="native,mjx")
    ap.add_argument("--around", default=None, help="JSON with a 'vector' to search around")
    ap.add_argument("--radius", type=float, default=0.15)
    ap.add_argument("--verify-only", action="store_true",
                    help="no optimisation: verify the gait of --around and merge into --out")
    ap.add_argument("--robust", type=int, default=0, help="randomised worlds per ant (0: none)")
    ap.add_argument("--aggregate", default="cvar", choices=["cvar", "worst", "mean"])
    ap.add_argument("--alpha", type=float, default=0.25, help="CVaR fraction of worst worlds")
    ap.add_argument("--world-seed", type=int, default=0)
    ap.add_argument("--penalty", default=None, choices=["cot", "power"])
    ap.add_argument("--penalty-weight", type=float, default=0.0)
    ap.add_argument("--trials", type=int, default=0, help="randomised validation trials")
    ap.add_argument("--trial-seed", type=int, default=0)
    ap.add_argument("--accurate-trials", action="store_true")
    ap.add_argument("--out", default="experiments/results/nao_best_gait.json")
    args = ap.parse_args()
    if args.verify_only:
        verify_only(args)
        return

    robust = RobustConfig(R=args.robust, aggregate=args.aggregate, alpha=args.alpha,
                          seed=args.world_seed) if args.robust else None
    problem = make_gait_problem(args.robot, backend=args.backend, horizon=args.horizon,
                                direction_deg=args.direction, slope_deg=args.slope,
                                robust=robust, penalty=args.penalty,
                                penalty_weight=args.penalty_weight)
    full_lo, full_hi = np.asarray(problem.lower), np.asarray(problem.upper)
    if args.around:
        centre = np.asarray(json.loads(Path(args.around).read_text())["vector"], np.float32)
        half = args.radius * (full_hi - full_lo)
        lo = np.maximum(full_lo, centre - half).astype(np.float32)
        hi = np.minimum(full_hi, centre + half).astype(np.float32)
        problem = problem.replace(lower=jnp.asarray(lo), upper=jnp.asarray(hi))
    strategy = ContinuousEACO(num_ants=args.ants, archive_size=args.archive, refine_ants=0,
                              repair_steps=0)
    t0 = time.time()

    def report(state, progress) -> bool:
        print(f"iter {progress.iterations:4d}  best fitness {-float(state.best_cost):.3f} m"
              f"  ({time.time() - t0:.0f} s)", flush=True)
        return False  # a progress report, never a stop

    result = ea.minimize(problem, strategy, seed=args.seed,
                         iterations=args.iterations, chunk_size=max(1, args.iterations // 10),
                         callback=report)
    best = np.asarray(result.best_solution, np.float32)
    seconds = time.time() - t0
    evaluations = int(np.asarray(result.evaluations))
    worlds = args.robust or 1
    steps = evaluations * worlds * problem.n_steps * round(problem.spec.control_dt / 0.004)
    print(f"optimised in {seconds:.0f} s, {evaluations} gaits x {worlds} worlds of "
          f"{args.horizon} s (~{steps / seconds:.0f} physics steps/s incl. compile)")
    verified = verify(problem, best, args)
    out = {
        "info": run_info(problem),
        "robot": args.robot,
        "slope_deg": args.slope,
        "direction_deg": args.direction,
        "params": problem.params_dict(best),
        "vector": best.tolist(),
        "optimisation": {
            "robust": None if robust is None else dict(vars(robust)),
            "penalty": args.penalty, "penalty_weight": args.penalty_weight,
            "backend": problem.backend, "horizon": args.horizon, "ants": args.ants,
            "archive": args.archive, "iterations": args.iterations, "seed": args.seed,
            "best_fitness": -float(result.best_cost), "evaluations": evaluations,
            "seconds": seconds, "around": args.around, "radius": args.radius if args.around
            else None,
            "history_best": [-float(v) for v in np.asarray(result.history["best_cost"])],
        },
        "verify_horizon": args.verify_horizon,
        "verified": verified,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.out}")


def verify(problem, vec: np.ndarray, args: argparse.Namespace) -> dict:
    """Nominal 20 s run (with energy / gait-quality metrics) and randomised trials per backend."""
    verified = {}
    print(f"\n{'backend':8s} {'horizon':>7s} {'speed':>7s} {'dist':>7s} {'fell':>5s} {'drift':>6s}"
          f" {'power':>6s} {'CoT':>5s}  trials: falls / n, speed +- ci95")
    nominal = problem.replace(robust=None, penalty=None, horizon=args.verify_horizon)
    for backend in [b for b in args.verify_backends.split(",") if b]:
        t0 = time.time()
        sim = nominal.simulate(vec, record=False, backend=backend)
        res = {k: sim[k] for k in KEYS}
        q = sim.get("quality", {})
        res["quality"] = q
        line = (f"{backend:8s} {args.verify_horizon:7.1f} {sim['speed_mps']:7.3f} "
                f"{sim['distance_m']:7.3f} {sim['fell']!s:>5s} {sim['drift_deg']:6.1f} "
                f"{q.get('mean_power_w', float('nan')):6.1f} "
                f"{q.get('cost_of_transport', float('nan')):5.2f}")
        if args.trials:
            runs = [("trials", False)] + ([("trials_accurate", True)]
                                          if args.accurate_trials and backend == "native" else [])
            for key, accurate in runs:
                tr = evaluate_trials(nominal.replace(backend=backend), vec, n=args.trials,
                                     seed=args.trial_seed, accurate=accurate,
                                     config=problem.robust)
                res[key] = tr
                line += (f"  {'acc ' if accurate else ''}{tr['falls']}/{tr['n']}, "
                         f"{tr['speed_mps_mean']:.3f} +- {tr['speed_mps_ci95']:.3f}")
        res["seconds"] = time.time() - t0
        verified[backend] = res
        print(line, flush=True)
    return verified


def verify_only(args: argparse.Namespace) -> None:
    """Re-simulate a stored gait on the requested backends; merge the results into --out."""
    if not args.around:
        raise SystemExit("--verify-only needs --around PARAMS.json")
    raw = json.loads(Path(args.around).read_text())
    slope = float(raw.get("slope_deg", args.slope))
    direction = float(raw.get("direction_deg", args.direction))
    problem = make_gait_problem(raw.get("robot", args.robot), backend="native",
                                horizon=args.verify_horizon, direction_deg=direction,
                                slope_deg=slope)
    vec = np.asarray(raw["vector"], np.float32)
    verified = dict(raw.get("verified", {}))
    verified.update(verify(problem, vec, args))
    raw["verified"] = verified
    raw["verify_horizon"] = args.verify_horizon
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(raw, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
