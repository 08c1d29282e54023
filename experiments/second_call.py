"""A second ``minimize`` call with the same shapes compiles nothing (issue 14, item 4).

For each problem: the first call (compiles the chunk), a second call with another seed and
other hyper-parameter values (same shapes: the compiled chunk is reused), and a third call
in a fresh process with JAX's persistent compilation cache warm (``--cache DIR``). Prints a
table and writes JSON (default ``results/second_call.json``).

    python experiments/second_call.py
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results" / "second_call.json"
CASES = {"eil51": ("eil51", "GraphEACO", 200), "g01": ("g01", "ContinuousEACO", 200)}


def one(case: str, cache: str | None) -> list[dict]:
    """Two calls in this process; each: wall seconds, compile seconds, best."""
    import jax

    if cache:
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    import eaco_jax as ea

    name, strategy_name, iterations = CASES[case]
    problem = ea.problems.get(name)
    strategy = getattr(ea.strategies, strategy_name)()
    params = strategy.default_params(problem)
    rows = []
    for call, (seed, p) in enumerate([(0, params), (1, params.replace(q0=params.q0 * 0.5))]):
        t0 = time.perf_counter()
        res = ea.minimize(problem, strategy, seed=seed, params=p, iterations=iterations)
        rows.append({"call": call + 1, "wall_seconds": time.perf_counter() - t0,
                     "compile_seconds": float(res.compile_seconds),
                     "best_cost": float(res.best_cost)})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        case, cache = args.child
        print(json.dumps(one(case, cache)))
        return
    import jax

    out = {"device": jax.devices()[0].device_kind, "jax": jax.__version__,
           "python": platform.python_version(), "cases": {}}
    print(f"{'case':>6} {'process':>22} {'call':>4} {'wall s':>8} {'compile s':>10}")
    for case in CASES:
        with tempfile.TemporaryDirectory() as cache:
            runs = {}
            for label in ("fresh cache", "warm persistent cache"):
                text = subprocess.run([sys.executable, __file__, "--child", case, cache],
                                      capture_output=True, text=True, check=True).stdout
                runs[label] = json.loads(text.strip().splitlines()[-1])
                for r in runs[label]:
                    print(f"{case:>6} {label:>22} {r['call']:>4} {r['wall_seconds']:8.2f} "
                          f"{r['compile_seconds']:10.2f}")
        out["cases"][case] = runs
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
