"""Gait colony evaluation on one device vs split over all local devices.

The split is :func:`eaco_jax.problems.sharding.shard`.

Evaluates the same colony of NAO gaits (MJX backend) once on the first device and once sharded
over every local device, checks the fitness values agree, and prints physics steps/s of each.

    python experiments/multi_device_gait.py --batch 8192 --horizon 1.0

Writes ``experiments/results/multi_device_gait_<n>dev.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.gait.rollout_native import native_model, substeps
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.problems.sharding import shard


def timed(fn, x, repeats: int) -> tuple[np.ndarray, float, float]:
    t0 = time.perf_counter()
    out = np.asarray(jax.block_until_ready(fn(x)))
    first = time.perf_counter() - t0
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(x))
        walls.append(time.perf_counter() - t0)
    return out, first, float(np.median(walls))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=8192)
    ap.add_argument("--horizon", type=float, default=1.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()

    problem = make_gait_problem("nao", backend="mjx", horizon=args.horizon)
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    rng = np.random.default_rng(0)
    x = jnp.asarray(lo + (hi - lo) * rng.random((args.batch, problem.dim)), jnp.float32)
    steps = problem.n_steps * substeps(problem.spec, native_model(problem.spec, 0.0, "fast"))
    devices = jax.local_devices()
    rows = []
    ref = None
    for label, prob in (("1 device", problem), (f"{len(devices)} devices", shard(problem))):
        fn = jax.jit(lambda a, p=prob: p.evaluate(a).f)
        f, first, wall = timed(fn, x, args.repeats)
        ref = f if ref is None else ref
        rows.append({"setup": label, "devices": 1 if prob is problem else len(devices),
                     "first_call_s": first, "wall_s": wall,
                     "steps_per_s": steps * args.batch / wall,
                     "max_abs_diff_vs_1_device": float(np.max(np.abs(f - ref)))})
        r = rows[-1]
        print(f"{label:>10}: {r['steps_per_s']:14,.0f} steps/s  wall {wall:.3f} s  "
              f"(first call {first:.1f} s)  max |f - f_1dev| {r['max_abs_diff_vs_1_device']:.2e}",
              flush=True)
    record = {"device_kind": devices[0].device_kind, "num_devices": len(devices),
              "batch": args.batch, "physics_steps": steps, "rows": rows}
    out = args.out or (Path(__file__).resolve().parent / "results" /
                       f"multi_device_gait_{len(devices)}dev.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
