"""The don't-look-bit local search, XLA loop against native (numba) code, on one CPU.

Times ``dlb_local_search(..., impl="xla" | "native")`` on the same random tours (after a
warm-up call: compile time apart), checks that both return the same tours and prints a
table; writes ``results/local_search_native_speed.json``. Run pinned to one core::

    taskset -c 0 python experiments/local_search_native_speed.py
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from common import find_instance, write_results

RESULTS = Path(__file__).resolve().parent / "results" / "local_search_native_speed.json"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", nargs="+", default=["pcb442", "pr1002"])
    ap.add_argument("--tours", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()

    import jax
    import numpy as np

    from eaco_jax.ops.local_search import dlb_local_search

    rows = []
    print(f"{'instance':>8} {'search':>11} {'xla ms':>8} {'native ms':>10} {'speed-up':>8}"
          f" {'same tours':>10}")
    for name in args.instances:
        p = find_instance(name)
        rng = np.random.default_rng(0)
        tours = np.stack([rng.permutation(p.n) for _ in range(args.tours)]).astype(np.int32)
        key = jax.random.key(0)
        for or_opt in (False, True):
            times, outs = {}, {}
            for impl in ("xla", "native"):
                def call(impl=impl, tours=tours, p=p, or_opt=or_opt, key=key):
                    out = dlb_local_search(key, tours, p.dist, p.neighbors, or_opt=or_opt,
                                           impl=impl)
                    return np.asarray(jax.block_until_ready(out))
                outs[impl] = call()  # compile (and numba's) apart
                samples = []
                for _ in range(args.repeats):
                    t0 = time.perf_counter()
                    call()
                    samples.append(time.perf_counter() - t0)
                times[impl] = statistics.median(samples)
            same = bool(np.array_equal(outs["xla"], outs["native"]))
            label = "2opt+oropt" if or_opt else "2opt-dlb"
            rows.append({"instance": name, "n": int(p.n), "tours": args.tours,
                         "local_search": label, "xla_seconds": times["xla"],
                         "native_seconds": times["native"],
                         "speedup": times["xla"] / times["native"], "same_tours": same})
            print(f"{name:>8} {label:>11} {1e3 * times['xla']:8.1f} "
                  f"{1e3 * times['native']:10.1f} {times['xla'] / times['native']:8.1f}"
                  f" {str(same):>10}", flush=True)
    write_results(args.out, rows, what="dlb local search of random tours from the same "
                  "state, median of repeats after a warm-up call")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
