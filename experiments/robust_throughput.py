"""Robust gait evaluation throughput: ants x R randomised worlds per call, in physics steps/s,
beside the raw physics rate of the same model and batch.

For each backend and ``(ants, R)`` it measures, after compilation, the median over ``--repeats``
calls of

* **robust** steps/s: ``GaitProblem.evaluate`` of a robust problem (``RobustConfig(R)``), jitted:
  walk engine, per-world targets (latency, noise), pushes, ants x R rollouts in one batched call
  with a model per world, fitness and its CVaR over worlds; counted as ants x R x physics steps /
  wall seconds. ``--quality`` also accumulates the energy / gait-quality metrics.
* **raw** steps/s: the nominal model, the same batch (ants x R) and number of physics steps with
  constant controls: ``lax.scan`` over ``jax.vmap(mjx.step)`` for ``mjx``; one
  ``mujoco.rollout`` call on all CPU threads for ``native``.

CPU::

    python experiments/robust_throughput.py --backend native,mjx --ants 4,16 --worlds 8 --horizon 1

GPU (the lead's)::

    python experiments/robust_throughput.py --backend mjx --ants 512,2048 --worlds 8 --horizon 4

Writes ``experiments/results/robust_throughput_<device>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from common import timed
from mujoco import rollout as mj_rollout

from eaco_jax.gait.rollout_mjx import mjx_model
from eaco_jax.gait.rollout_native import initial_state, native_model, substeps
from eaco_jax.gait.walk_engine import LOWER, UPPER
from eaco_jax.gait.worlds import RobustConfig, world_key
from eaco_jax.problems.gait import make_gait_problem

RESULTS = Path(__file__).resolve().parent / "results"


def robust_rate(backend: str, ants: int, r: int, horizon: float, repeats: int,
                quality: bool) -> dict[str, Any]:
    penalty = "cot" if quality else None
    p = make_gait_problem("nao", backend=backend, horizon=horizon, robust=RobustConfig(R=r),
                          penalty=penalty, penalty_weight=0.1 if quality else 0.0)
    x = jnp.asarray(LOWER + (UPPER - LOWER) * np.random.default_rng(0).random((ants, len(LOWER))),
                    jnp.float32)
    fn = jax.jit(lambda x, k: p.evaluate(x, k).f)
    first, wall = timed(lambda: fn(x, world_key(0, 0)), repeats)
    k = substeps(p.spec, native_model(p.spec, 0.0, "fast"))
    steps = ants * r * p.n_steps * k
    return {"first_call_s": first, "wall_s": wall, "steps_per_s": steps / wall}


def raw_rate(backend: str, batch: int, horizon: float, repeats: int) -> dict[str, Any]:
    p = make_gait_problem("nao", backend=backend, horizon=horizon)
    model = native_model(p.spec, 0.0, "fast")
    k = substeps(p.spec, model)
    nstep = p.n_steps * k
    state0 = initial_state(p.spec, model, 0.0)
    ctrl = np.asarray(p.spec.stand_ctrl)
    if backend == "native":
        nthread = os.cpu_count() or 1
        pool = mj_rollout.Rollout(nthread=nthread)
        datas = [mujoco.MjData(model) for _ in range(nthread)]
        states = np.tile(state0, (batch, 1))
        controls = np.tile(ctrl, (batch, nstep, 1))
        first, wall = timed(lambda: pool.rollout(model, datas, states, controls)[0][:, -1, 0],
                            repeats)
    else:
        from mujoco import mjx

        mm = mjx_model(p.spec, 0.0, "fast")
        d = mjx.make_data(mm).replace(qpos=jnp.asarray(state0[1:1 + model.nq], jnp.float32),
                                      ctrl=jnp.asarray(ctrl, jnp.float32))
        d = jax.tree.map(lambda a: jnp.broadcast_to(a, (batch,) + a.shape), mjx.forward(mm, d))
        step = jax.vmap(lambda dd: mjx.step(mm, dd))
        run = jax.jit(lambda dd: jax.lax.scan(lambda c, _: (step(c), None), dd, None,
                                              length=nstep)[0].qpos)
        first, wall = timed(lambda: run(d), repeats)
    return {"first_call_s": first, "wall_s": wall, "steps_per_s": batch * nstep / wall}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="native,mjx")
    ap.add_argument("--ants", default="4,16")
    ap.add_argument("--worlds", default="8")
    ap.add_argument("--horizon", type=float, default=1.0)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--quality", action="store_true", help="also accumulate energy metrics")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    device = jax.devices()[0].device_kind if jax.default_backend() != "cpu" else "cpu"
    rows = []
    for backend in args.backend.split(","):
        for ants in (int(a) for a in args.ants.split(",")):
            for r in (int(w) for w in args.worlds.split(",")):
                row = {"backend": backend, "ants": ants, "R": r, "batch": ants * r,
                       "horizon": args.horizon, "quality": args.quality}
                row["robust"] = robust_rate(backend, ants, r, args.horizon, args.repeats,
                                            args.quality)
                row["raw"] = raw_rate(backend, ants * r, args.horizon, args.repeats)
                row["ratio"] = row["robust"]["steps_per_s"] / row["raw"]["steps_per_s"]
                rows.append(row)
                print(f"{backend:6s} ants {ants:5d} x R {r:3d}: robust "
                      f"{row['robust']['steps_per_s']:10.0f} steps/s, raw "
                      f"{row['raw']['steps_per_s']:10.0f} steps/s, ratio {row['ratio']:.2f} "
                      f"(first call {row['robust']['first_call_s']:.0f} s)", flush=True)
    out = Path(args.out or RESULTS / f"robust_throughput_{device.replace(' ', '_').lower()}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"device": device, "cpus": os.cpu_count(),
                               "machine": platform.machine(), "rows": rows}, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
