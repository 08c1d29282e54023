"""Tours/s of the construction kernel against its block size (ants per program).

For each instance, colony size and block size of ``eaco_jax.ops.construction_kernel``, times
one jitted construction on the initial weights (median of ``--repeats``), checks its tours
against plan "compact" from the same draws, and writes JSON:

    python experiments/tsp_kernel_variants.py --instances pr1002 --ants 4096 --blocks 32 128

``results/gpu/tsp_kernel_variants_h100.json`` also compares the kernel's fallback variants,
measured at commit 6fcba9e, which had them as a switch: backup lists unrolled over the block,
as (block, 64) tiles or one pending ant at a time; whole rows as (block, 128) tiles or one ant
at a time ("skip": left out, wrong tours, to time the rest). The code keeps the fastest, one
ant at a time for both.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from tsp_bench_common import device_info, find_instance  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", nargs="+", default=["pr1002"])
    ap.add_argument("--ants", type=int, nargs="+", default=[4096])
    ap.add_argument("--blocks", type=int, nargs="+", default=[32, 128])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("results/tsp_kernel_variants.json"))
    args = ap.parse_args()

    import jax
    import jax.numpy as jnp

    from eaco_jax.ops import construction_kernel as ck
    from eaco_jax.ops.construction import choice_weights, construct_tours, heuristic_log_eta

    info = device_info()
    rows = []
    print(f"{info['device']}, jax {info['jax']}")
    print(f"{'instance':>8} {'ants':>6} {'block':>5} {'tours/s':>12} {'compile s':>9} "
          f"{'same':>5}")
    for name in args.instances:
        problem = find_instance(name)
        n = problem.n
        w = choice_weights(jnp.ones((n, n), jnp.float32), heuristic_log_eta(problem.dist),
                           jnp.float32(1.0), jnp.float32(2.0))
        for m in args.ants:
            starts = jax.random.randint(jax.random.key(1), (m,), 0, n, jnp.int32)

            def build(plan):
                return jax.jit(lambda key, wt, s, c: construct_tours(key, wt, s, 0.0,
                                                                    candidates=c,
                                                                    fallback=plan))

            fargs = (w, starts, problem.neighbors)
            reference = build("compact")(jax.random.key(0), *fargs).block_until_ready()
            for block in args.blocks:
                ck.BLOCK = block
                row = {"instance": name, "n": n, "ants": m, "block": block}
                try:
                    fn = build("kernel")
                    t0 = time.perf_counter()
                    compiled = fn.lower(jax.random.key(0), *fargs).compile()
                    row["compile_seconds"] = time.perf_counter() - t0
                    tours = compiled(jax.random.key(0), *fargs).block_until_ready()
                    row["same_tours"] = float(jnp.mean(jnp.all(tours == reference, axis=1)))
                    times = []
                    for _ in range(args.repeats):
                        t0 = time.perf_counter()
                        compiled(jax.random.key(0), *fargs).block_until_ready()
                        times.append(time.perf_counter() - t0)
                        if times[-1] > 2.0:  # slow variants: one timing is enough
                            break
                    row["seconds"] = statistics.median(times)
                    row["tours_per_second"] = m / row["seconds"]
                except Exception as exc:  # record a variant that does not compile, go on
                    row["error"] = f"{type(exc).__name__}: {str(exc)[:400]}"
                rows.append(row)
                args.out.parent.mkdir(parents=True, exist_ok=True)
                args.out.write_text(json.dumps({"info": info, "argv": sys.argv[1:],
                                                "rows": rows}, indent=1) + "\n")
                print(f"{name:>8} {m:>6} {block:>5} "
                      f"{row.get('tours_per_second', float('nan')):12,.0f} "
                      f"{row.get('compile_seconds', float('nan')):9.1f} "
                      f"{row.get('same_tours', float('nan')):5.3f} {row.get('error', '')[:80]}",
                      flush=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
