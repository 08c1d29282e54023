"""Which local search earns its time? Gap reached in a fixed wall time, per configuration.

Each configuration (local search kind x ``ls_best_k``) runs the default ``GraphEACO`` colony
(``--ants`` ants) through ``eaco_jax.minimize`` for ``--seconds`` of search after compilation
(compile time reported apart), per instance and seed. Rounds are interleaved (seed-major, every
configuration once per seed in turn) so that a drifting machine affects all alike; still, this
2-core host is shared and absolute times are noisy: compare configurations within a run.
Writes ``experiments/results/tsp_ls_choice.json`` and prints a table of mean gaps.

    taskset -c 1 python experiments/tsp_ls_choice.py                     # CPU defaults
    python experiments/tsp_ls_choice.py --instances pr1002 --ants 1024 --seconds 10   # GPU
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from common import (
    best_at,
    enable_compile_cache,
    find_instance,
    run_timed,
    write_results,
)

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_ls_choice.json"
SECONDS = {"eil51": 3.0, "kroA100": 3.0, "a280": 6.0, "pcb442": 10.0}


def configs(ants: int, quarter: bool) -> list[tuple[str, str, int | None]]:
    """(label, local_search, ls_best_k) of every configuration compared."""
    k = max(1, ants // 4)
    out = [("2opt", "2opt", None), ("2opt-dlb", "2opt-dlb", None),
           ("2opt+oropt", "2opt+oropt", None), ("or-2opt", "or-2opt", None)]
    if quarter:
        out += [(f"2opt-dlb/best{k}", "2opt-dlb", k), (f"2opt+oropt/best{k}", "2opt+oropt", k),
                (f"2opt/best{k}", "2opt", k), (f"or-2opt/best{k}", "or-2opt", k)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", nargs="+", default=list(SECONDS))
    ap.add_argument("--seconds", type=float, help="budget per run (default: per instance)")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--ants", type=int, default=40)
    ap.add_argument("--chunk", type=int, default=5)
    ap.add_argument("--no-best-k", action="store_true", help="skip the ls_best_k variants")
    ap.add_argument("--configs", nargs="+", help="run only these labels (e.g. or-2opt/best10)")
    ap.add_argument("--data-dir", type=Path, action="append")
    ap.add_argument("--cache-dir", type=Path, default=Path("out/jax_cache"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    enable_compile_cache(args.cache_dir)
    from eaco_jax.strategies.graph_eaco import GraphEACO

    rows = []
    for name in args.instances:
        problem = find_instance(name, args.data_dir)
        seconds = args.seconds or SECONDS.get(name, 10.0)
        runs: dict[str, list] = {}
        for seed in range(args.seeds):
            for label, ls, k in configs(args.ants, not args.no_best_k):
                if args.configs and label not in args.configs:
                    continue
                strategy = GraphEACO(num_ants=args.ants, local_search=ls, ls_best_k=k)
                r = run_timed(problem, strategy, seed, seconds, args.chunk)
                r["gap_percent"] = 100.0 * (r["best"] / problem.optimum - 1.0)
                runs.setdefault(label, []).append(r)
                print(f"{name:>8} {label:>20} seed {seed}: gap {r['gap_percent']:.3f}% "
                      f"iters {r['iterations']} compile {r['compile_seconds']:.1f}s", flush=True)
        for label, rs in runs.items():
            half = [100.0 * (best_at(r["trace"], seconds / 2) / problem.optimum - 1.0)
                    for r in rs if best_at(r["trace"], seconds / 2) is not None]
            rows.append({
                "instance": name, "config": label, "seconds": seconds, "ants": args.ants,
                "mean_gap_percent": statistics.mean(r["gap_percent"] for r in rs),
                "gaps_percent": [r["gap_percent"] for r in rs],
                "mean_gap_at_half_percent": statistics.mean(half) if half else None,
                "mean_iterations": statistics.mean(r["iterations"] for r in rs),
                "runs": rs})
    print(f"\n{'instance':>8} {'config':>20} {'s':>5} {'gap% mean':>10} {'gap%@s/2':>9} "
          f"{'iters':>7}")
    for r in rows:
        half = r["mean_gap_at_half_percent"]
        print(f"{r['instance']:>8} {r['config']:>20} {r['seconds']:5.1f} "
              f"{r['mean_gap_percent']:10.3f} {half if half is not None else float('nan'):9.3f} "
              f"{r['mean_iterations']:7.0f}")
    write_results(args.out, rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
