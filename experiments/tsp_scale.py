"""Tours per second against colony size, without local search (issue 15, item 1).

For each instance and colony size (``--ants``, default 1k-64k) and each construction plan
(``--fallbacks``: the scan plans ``lazy dense backup compact``, the Pallas ``kernel`` and
``kernelB`` for B ants per program, or ``auto``; every plan builds the same tours, see
``construction.construct_tours``; each row records the share of its tours identical to the
first plan's, from the same draws):

* the colony: ``eaco_jax.minimize(problem, GraphEACO(num_ants=m, local_search="none"),
  iterations=--iterations)``; tours/s = m / seconds per iteration after compilation
  (``Result.seconds_per_iteration``), compile seconds reported apart;
* construction alone (``construct_tours`` on the initial weights, jitted, median of
  ``--repeats`` calls): its tours/s and a roofline estimate. The model counts the bytes one
  ant-step must move at least (candidate ids, choice info and tabu bytes of its k candidates,
  its uniform, the path write, the tabu update: ``9 k + 9`` bytes), so roofline fraction =
  model bytes per second / the device's peak memory bandwidth (``--peak-gbs``, default from
  the device name; none on CPU). Random 1-byte tabu gathers really move whole sectors, so
  the achievable fraction is well below 1;
* a memory estimate of the construction's live arrays (tabu mask, uniforms, path, weights).

Prints a table and writes JSON (device, jax version, every measurement). Runs small on CPU:

    python experiments/tsp_scale.py --instances pcb442 --ants 64 256 --iterations 3
    python experiments/tsp_scale.py --data-dir /path/to/tsplib   # GPU: pcb442 rat783 pr1002 d2103
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from common import device_info, enable_compile_cache, find_instance

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_scale.json"
PEAK_GBS = {"H100 80GB HBM3": 3350.0, "H100 SXM": 3350.0, "H100 PCIe": 2000.0,
            "H200": 4800.0, "A100-SXM4-80GB": 2039.0, "A100-SXM4-40GB": 1555.0,
            "Tesla V100-SXM2-16GB": 900.0}


def peak_gbs(device: str) -> float | None:
    """Peak memory bandwidth (GB/s) of a known device name, else None."""
    for name, gbs in PEAK_GBS.items():
        if name.lower() in device.lower() or device.lower() in name.lower():
            return gbs
    if "h100" in device.lower():
        return 3350.0
    if "h200" in device.lower():
        return 4800.0
    return None


#: the library's ants per program of the kernel plan, before any "kernelB" row changed it
_DEFAULT_BLOCK: list[int] = []


def use_plan(name: str) -> tuple[str, int | None]:
    """(construction plan, kernel block) of a plan name; "kernelB" sets the kernel's ants per
    program to B for this row (its module constant), "kernel" restores the library's."""
    if not name.startswith("kernel"):
        return name, None
    from eaco_jax.ops import construction_kernel

    if not _DEFAULT_BLOCK:
        _DEFAULT_BLOCK.append(construction_kernel.BLOCK)
    construction_kernel.BLOCK = int(name[len("kernel"):] or _DEFAULT_BLOCK[0])
    return "kernel", construction_kernel.BLOCK


def memory_bytes(m: int, n: int, k: int) -> dict:
    """Live arrays of one construction (bytes)."""
    return {"tabu_mask": m * n, "uniforms": 4 * m * (n - 1), "path": 4 * m * (n - 1),
            "tours": 4 * m * n, "weights_stacked": 2 * 4 * n * n, "choice_info": 2 * 8 * n * k}


def time_construction(problem, m: int, fallback: str, repeats: int) -> tuple[dict, Any]:
    """Median seconds of one jitted construction of m tours on the initial weights."""
    import jax
    import jax.numpy as jnp

    from eaco_jax.ops.construction import choice_weights, construct_tours, heuristic_log_eta

    n = problem.n
    w = choice_weights(jnp.ones((n, n), jnp.float32), heuristic_log_eta(problem.dist),
                       jnp.float32(1.0), jnp.float32(2.0))
    starts = jax.random.randint(jax.random.key(1), (m,), 0, n, jnp.int32)
    # weights and lists are arguments, not constants: XLA would fold the backup top_k
    fn = jax.jit(lambda key, w, starts, cand: construct_tours(key, w, starts, 0.0,
                                                              candidates=cand,
                                                              fallback=fallback))
    args = (w, starts, problem.neighbors)
    t0 = time.perf_counter()
    compiled = fn.lower(jax.random.key(0), *args).compile()
    compile_s = time.perf_counter() - t0
    keys = jax.random.split(jax.random.key(2), repeats + 1)
    tours = compiled(keys[0], *args).block_until_ready()
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        compiled(keys[i + 1], *args).block_until_ready()
        times.append(time.perf_counter() - t0)
    return {"construct_seconds": statistics.median(times),
            "construct_compile_seconds": compile_s}, tours


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", nargs="+", default=["pcb442", "rat783", "pr1002", "d2103"])
    ap.add_argument("--ants", type=int, nargs="+", default=[1024, 4096, 16384, 65536])
    ap.add_argument("--fallbacks", nargs="+", default=["auto"],
                    help="construction plans to compare (auto lazy dense backup compact kernel; "
                         "kernelB: the kernel with B ants per program)")
    ap.add_argument("--iterations", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--skip-colony", action="store_true", help="construction timing only")
    ap.add_argument("--peak-gbs", type=float, help="device memory bandwidth for the roofline")
    ap.add_argument("--data-dir", type=Path, action="append")
    ap.add_argument("--cache-dir", type=Path, default=Path("out/jax_cache"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    enable_compile_cache(args.cache_dir)

    import jax.numpy as jnp

    from eaco_jax import minimize
    from eaco_jax.strategies.graph_eaco import GraphEACO

    info = device_info()
    peak = args.peak_gbs or peak_gbs(info["device"])
    rows = []
    print(f"{info['device']} ({info['backend']}), jax {info['jax']}, peak "
          f"{peak or float('nan'):.0f} GB/s")
    print(f"{'instance':>8} {'ants':>6} {'fallback':>8} {'colony tours/s':>15} {'ms/it':>8} "
          f"{'compile s':>9} {'constr tours/s':>15} {'model GB/s':>10} {'roofline':>8} "
          f"{'mem MB':>8}")
    def save(rows: list) -> None:  # after every row: a run cut short keeps what it measured
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"info": info, "peak_gbs": peak, "argv": sys.argv[1:],
                                        "rows": rows}, indent=1) + "\n")

    for name in args.instances:
        problem = find_instance(name, args.data_dir)
        n, k = problem.n, int(problem.neighbors.shape[1])
        for m in args.ants:
            reference = None
            for fb in args.fallbacks:
                row = {"instance": name, "n": n, "k": k, "ants": m, "fallback": fb}
                try:
                    plan, row["kernel_block"] = use_plan(fb)
                    timing, tours = time_construction(problem, m, plan, args.repeats)
                    row.update(timing)
                    # the plans' tours from the same draws: the share identical to the first
                    # plan's (the kernel's prefix sums add in another order)
                    if reference is None:
                        reference = tours
                    row["same_tours_as_first_plan"] = float(
                        jnp.mean(jnp.all(tours == reference, axis=1)))
                    del tours
                    if not args.skip_colony:
                        strategy = GraphEACO(num_ants=m, local_search="none",
                                             construction_fallback=plan)
                        res = minimize(problem, strategy, seed=0, iterations=args.iterations,
                                       chunk_size=max(1, args.iterations // 4))
                        row.update(colony_seconds_per_iteration=res.seconds_per_iteration,
                                   colony_tours_per_second=m / res.seconds_per_iteration,
                                   colony_compile_seconds=res.compile_seconds,
                                   best_length=float(res.best_cost))
                except Exception as exc:  # out of memory at the largest sizes: record, go on
                    row["error"] = f"{type(exc).__name__}: {str(exc)[:300]}"
                    print(f"{name:>8} {m:>6} {fb:>8} failed: {row['error'][:100]}", flush=True)
                    rows.append(row)
                    continue
                model = m * (n - 1) * (9 * k + 9)
                row["model_bytes"] = model
                row["construct_tours_per_second"] = m / row["construct_seconds"]
                row["model_gbs"] = model / row["construct_seconds"] / 1e9
                row["roofline_fraction"] = row["model_gbs"] / peak if peak else None
                mem = memory_bytes(m, n, k)
                row["memory_bytes"] = mem
                rows.append(row)
                save(rows)
                ct = row.get("colony_tours_per_second", float("nan"))
                ms = 1000 * row.get("colony_seconds_per_iteration", float("nan"))
                cs = row.get("colony_compile_seconds", float("nan"))
                rf = row["roofline_fraction"]
                print(f"{name:>8} {m:>6} {fb:>8} {ct:15,.0f} {ms:8.2f} {cs:9.1f} "
                      f"{row['construct_tours_per_second']:15,.0f} {row['model_gbs']:10.1f} "
                      f"{rf if rf is not None else float('nan'):8.3f} "
                      f"{sum(mem.values()) / 1e6:8.0f}", flush=True)
    save(rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
