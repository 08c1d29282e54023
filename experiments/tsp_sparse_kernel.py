"""The sparse construction's Pallas kernel against its scan, compiled on a GPU (issue #33, item 2).

    python experiments/tsp_sparse_kernel.py --sizes 3000 10000 --ants 96 1536 --caps 0 128

``construct_tours_sparse(..., plan="kernel")`` runs one Pallas (Triton) kernel per block of ants
on a GPU and in Pallas' interpreter elsewhere; ``tests/test_tsp_sparse.py`` checks on the CPU
that it builds the scan's tours. This checks the compiled kernel: for each random uniform
instance (``--sizes``, integer coordinates in [0, 10**6) drawn by ``default_rng([1, n])``:
not one of ``tsp_large.py``'s instances, and never reported on), colony size (``--ants``)
and focused-construction cap (``--caps``, 0: none), both plans build tours from the same
draws on the same random choice weights over the k-d tree's 16 nearest candidates, from the
Hilbert-curve tour; the row
records the share of ants whose tours are identical, whether every tour is a permutation,
and each plan's median seconds per construction over ``--repeats`` calls after compilation
(compile seconds apart). Prints a table and writes JSON (device, versions, command, date). On
a CPU keep it tiny (the interpreter is slow): ``--sizes 200 --ants 8 --repeats 1``.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from datetime import date
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from common import device_info, timed

from eaco_jax.ops.construction import kernel_compiles_here
from eaco_jax.ops.construction_sparse import construct_tours_sparse, hilbert_tour
from eaco_jax.outputs import write_json
from eaco_jax.problems.tsp_sparse import SparseTSP

HERE = Path(__file__).resolve().parent


def tours_and_times(fn, repeats: int) -> tuple[np.ndarray, float, float]:
    """``(tours, compile seconds, median seconds per call)`` of a jitted construction: the
    first call compiles and gives the tours, then :func:`common.timed` times warm calls."""
    t0 = time.perf_counter()
    out = np.asarray(jax.block_until_ready(fn()))
    first = time.perf_counter() - t0
    _, med = timed(fn, max(repeats, 1))
    return out, max(first - med, 0.0), med


def build(key, cand_w, candidates, starts, ref, *, plan: str, max_new_edges: int | None):
    """The colony's tours from ``ref`` on choice weights ``cand_w`` (q0 = 0)."""
    return construct_tours_sparse(key, cand_w, candidates, starts, ref, 0.0,
                                  max_new_edges=max_new_edges, plan=plan)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[3000, 10000])
    ap.add_argument("--ants", type=int, nargs="+", default=[96, 1536])
    ap.add_argument("--caps", type=int, nargs="+", default=[0, 128])
    ap.add_argument("--neighbors", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "tsp_large" /
                    "sparse_kernel.json")
    args = ap.parse_args()
    rows = []
    print(f"kernel compiled here: {kernel_compiles_here()}")
    print(f"{'n':>7} {'ants':>5} {'cap':>4} {'same':>6} {'perm':>5} {'scan s':>9} "
          f"{'kernel s':>9} {'speed-up':>8}")
    for n in args.sizes:
        rng = np.random.default_rng([1, n])  # not tsp_large.py's [n, seed]
        p = SparseTSP.from_coords(rng.integers(0, 10**6, (n, 2)), neighbors=args.neighbors)
        ref = hilbert_tour(p.coords)
        cand_w = jnp.asarray(rng.uniform(0.1, 1.0, (n, args.neighbors)), jnp.float32)
        for m in args.ants:
            starts = jnp.asarray(rng.integers(0, n, m), jnp.int32)
            for cap in args.caps:
                c = cap or None
                res = {}
                for plan in ("scan", "kernel"):
                    fn = jax.jit(functools.partial(build, plan=plan, max_new_edges=c),
                                 static_argnames=("plan", "max_new_edges"))
                    a = (cand_w, p.neighbors, starts, ref)
                    res[plan] = tours_and_times(lambda fn=fn, a=a: fn(jax.random.key(7), *a),
                                                args.repeats)
                ts, tk = res["scan"][0], res["kernel"][0]
                perm = bool(np.all(np.sort(tk, axis=1) == np.arange(n)[None, :]))
                row = {"n": n, "ants": m, "max_new_edges": cap, "k": args.neighbors,
                       "same_tour_share": float(np.mean(np.all(ts == tk, axis=1))),
                       "kernel_tours_are_permutations": perm,
                       "scan_seconds": res["scan"][2], "kernel_seconds": res["kernel"][2],
                       "scan_compile_seconds": res["scan"][1],
                       "kernel_compile_seconds": res["kernel"][1],
                       "scan_tours_per_s": m / res["scan"][2],
                       "kernel_tours_per_s": m / res["kernel"][2]}
                rows.append(row)
                print(f"{n:>7} {m:>5} {cap:>4} {row['same_tour_share']:>6.3f} {str(perm):>5} "
                      f"{row['scan_seconds']:>9.4f} {row['kernel_seconds']:>9.4f} "
                      f"{row['scan_seconds'] / row['kernel_seconds']:>8.2f}", flush=True)
    write_json(args.out, {
        "command": "python experiments/tsp_sparse_kernel.py " + " ".join(sys.argv[1:]),
        "date": str(date.today()), "device": device_info(),
        "kernel_compiled": kernel_compiles_here(),
        "seeds": {"instances": "random uniform, instance seed 1 per size (selection)",
                  "draws": "jax.random.key(7)"}, "rows": rows})


if __name__ == "__main__":
    main()
