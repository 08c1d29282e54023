"""Gait throughput: colony evaluation steps/s against the raw physics step rate of the same model.

For every backend and batch (= colony size) this measures, after compilation, the median over
``--repeats`` calls of

* **colony** steps/s: ``ea.minimize`` of ``--iterations`` ask -> ``GaitProblem.evaluate`` -> tell
  rounds of ``ContinuousEACO`` as one compiled chunk (``chunk_size=iterations``; the first call
  compiles, the timed ones reuse the cached chunk), counted as physics steps x ants x
  iterations / the chunk's seconds (``Result.seconds_per_iteration``, compilation excluded). It
  includes the walk engine (joint targets every control step), the fitness and the colony
  update.
* **raw** steps/s: the same model (same solver settings), the same batch and number of physics
  steps with constant controls and no controller: ``lax.scan`` over ``jax.vmap(mjx.step)`` for
  ``mjx``; one ``mujoco.rollout`` call on all CPU threads for ``native``.

* **evaluate** steps/s (unless ``--no-split``): ``GaitProblem.evaluate`` alone, jitted, on a
  fixed random colony: the controller and fitness without the colony update.

* **raw walking** steps/s (``mjx`` only): the same raw loop fed the colony's own controls
  (random gaits' walk-engine targets, precomputed): the physics of a walking colony, which
  costs more than a standing one because MJX's solver iterates until every ant converges.

``ratio = colony / raw`` is what the optimiser (controller, fitness, colony) costs; the target is
>= 0.9. ``ratio wlk = colony / raw walking`` separates the optimiser's own cost from the harder
physics of walking robots. ``eval/raw`` shows how much of that is the walk engine rather than
ask/tell. On CPU it also prints native against MJX at the same batch.

CPU (default)::

    python experiments/gait_throughput.py --batches 32,64,128 --backend mjx,native --steps 250

GPU (through ``device``)::

    python experiments/gait_throughput.py --batches 1024,4096,16384 --backend mjx --steps 1000

Writes ``experiments/results/gait_throughput_<device>.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import statistics
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from common import timed

import eaco_jax as ea
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_mjx import mjx_model
from eaco_jax.gait.rollout_native import initial_state, native_model, substeps
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.strategies.continuous_eaco import ContinuousEACO

RESULTS = Path(__file__).resolve().parent / "results"


def colony_rate(robot: str, backend: str, batch: int, control_steps: int, iterations: int,
                repeats: int, seed: int = 0) -> dict[str, Any]:
    """Physics steps/s of the jitted colony loop (ask, batched rollout + fitness, tell)."""
    spec = load_robot(robot)
    k = substeps(spec, native_model(spec, 0.0, "fast"))
    problem = make_gait_problem(robot, backend=backend, horizon=control_steps * spec.control_dt)
    assert problem.n_steps == control_steps
    strategy = ContinuousEACO(num_ants=batch, archive_size=max(2, batch // 2), refine_ants=0,
                              repair_steps=0)

    def call() -> ea.Result:
        return ea.minimize(problem, strategy, seed=seed, iterations=iterations,
                           chunk_size=iterations)

    first = call()  # compiles the chunk (cached for the timed calls)
    compile_s = first.compile_seconds
    results = [call() for _ in range(repeats)]
    wall = statistics.median(r.seconds_per_iteration * r.iterations for r in results)
    best = results[-1] if results else first
    steps = control_steps * k
    return {"compile_s": compile_s, "wall_s": wall, "physics_steps": steps,
            "steps_per_s": steps * batch * iterations / wall,
            "best_fitness": -float(np.asarray(best.best_cost))}


def evaluate_rate(robot: str, backend: str, batch: int, control_steps: int, repeats: int,
                  seed: int = 0) -> dict[str, Any]:
    """Physics steps/s of ``GaitProblem.evaluate`` alone (walk engine + physics + fitness, no
    colony): separates what the controller costs from what the colony update costs."""
    spec = load_robot(robot)
    k = substeps(spec, native_model(spec, 0.0, "fast"))
    problem = make_gait_problem(robot, backend=backend, horizon=control_steps * spec.control_dt)
    x = random_gaits(problem, batch, seed)
    t0 = time.perf_counter()
    fn = jax.jit(lambda a: problem.evaluate(a).f).lower(x).compile()
    compile_s = time.perf_counter() - t0
    _, wall = timed(lambda: fn(x), repeats)
    steps = control_steps * k
    return {"compile_s": compile_s, "wall_s": wall, "steps_per_s": steps * batch / wall}


def random_gaits(problem, batch: int, seed: int = 0) -> jax.Array:
    """``batch`` gait parameter vectors uniform in the problem's bounds."""
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    return jnp.asarray(lo + (hi - lo) * np.random.default_rng(seed).random((batch, problem.dim)),
                       jnp.float32)


def raw_mjx_rate(robot: str, batch: int, control_steps: int, repeats: int,
                 walking: bool = False, seed: int = 0) -> dict[str, Any]:
    """Physics steps/s of ``lax.scan`` over ``vmap(mjx.step)``: same model, batch, steps.

    ``walking=False`` holds the standing pose. ``walking=True`` feeds the colony's own kind of
    controls: random gaits' precomputed walk-engine targets, each held for ``substeps`` steps,
    nothing else in the loop. A walking colony makes the constraint solver work harder (MJX's
    solver loop runs until every batch member converges), so that is the physics-only rate of
    the work the colony does, and ``colony / raw walking`` is what the optimiser itself adds.
    """
    from mujoco import mjx

    spec = load_robot(robot)
    model = native_model(spec, 0.0, "fast")
    k = substeps(spec, model)
    steps = control_steps * k
    mm = mjx_model(spec, 0.0, "fast")
    qpos0 = jnp.asarray(initial_state(spec, model, 0.0)[1 : 1 + model.nq], jnp.float32)
    ctrl0 = jnp.asarray(spec.stand_ctrl, jnp.float32)
    data = mjx.forward(mm, mjx.make_data(mm).replace(qpos=qpos0, ctrl=ctrl0))
    batched = jax.tree.map(lambda a: jnp.broadcast_to(a, (batch,) + a.shape), data)
    step = jax.vmap(lambda d: mjx.step(mm, d))
    if walking:
        problem = make_gait_problem(robot, backend="mjx", horizon=control_steps * spec.control_dt)
        controls = jnp.swapaxes(jax.jit(problem.controls)(random_gaits(problem, batch, seed)),
                                0, 1)  # (T, batch, nu)

        def body(dd, i):
            return step(dd.replace(ctrl=controls[i // k])), None
    else:
        def body(dd, i):
            return step(dd), None

    @jax.jit
    def run(d):
        d, _ = jax.lax.scan(body, d, jnp.arange(steps))
        return d.qpos

    t0 = time.perf_counter()
    compiled = run.lower(batched).compile()
    compile_s = time.perf_counter() - t0
    _, wall = timed(lambda: compiled(batched), repeats)
    return {"compile_s": compile_s, "wall_s": wall, "physics_steps": steps,
            "steps_per_s": steps * batch / wall}


def raw_native_rate(robot: str, batch: int, steps: int, repeats: int) -> dict[str, Any]:
    """Physics steps/s of one ``mujoco.rollout`` call on all CPU threads (constant controls)."""
    import mujoco
    from mujoco import rollout as mj_rollout

    spec = load_robot(robot)
    model = native_model(spec, 0.0, "fast")
    nthread = os.cpu_count() or 1
    datas = [mujoco.MjData(model) for _ in range(nthread)]
    state = np.tile(initial_state(spec, model, 0.0), (batch, 1))
    ctrl = np.tile(np.asarray(spec.stand_ctrl, np.float64), (batch, steps, 1))
    with mj_rollout.Rollout(nthread=nthread) as pool:
        _, wall = timed(lambda: pool.rollout(model, datas, state, ctrl)[0], repeats)
    return {"compile_s": 0.0, "wall_s": wall, "physics_steps": steps,
            "steps_per_s": steps * batch / wall, "threads": nthread}


def _opt(value: float | None, fmt: str, width: int) -> str:
    return f"{value:{width}{fmt}}" if value is not None else f"{'-':>{width}s}"


def fmt_row(r: dict[str, Any]) -> str:
    return (f"{r['backend']:7s} {r['batch']:6d} {r['colony_steps_per_s']:15,.0f} "
            f"{_opt(r['evaluate_steps_per_s'], ',.0f', 17)} {r['raw_steps_per_s']:12,.0f} "
            f"{_opt(r['raw_walking_steps_per_s'], ',.0f', 14)} {r['ratio']:6.2f} "
            f"{_opt(r['ratio_walking'], '.2f', 9)} {_opt(r['evaluate_ratio'], '.2f', 8)} "
            f"{r['colony_compile_s']:9.1f}")


def device_label() -> str:
    dev = jax.devices()[0]
    kind = dev.platform if dev.platform == "cpu" else getattr(dev, "device_kind", dev.platform)
    return re.sub(r"[^a-z0-9]+", "_", str(kind).lower()).strip("_")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="nao")
    ap.add_argument("--batches", default="32,64,128", help="colony sizes, comma separated")
    ap.add_argument("--backend", default="mjx,native", help="mjx, native or both")
    ap.add_argument("--steps", type=int, default=250,
                    help="physics steps per rollout (rounded up to whole control steps)")
    ap.add_argument("--iterations", type=int, default=1, help="colony iterations per call")
    ap.add_argument("--repeats", type=int, default=3, help="timed calls (median)")
    ap.add_argument("--no-split", action="store_true",
                    help="skip timing GaitProblem.evaluate alone (one compile less per batch)")
    ap.add_argument("--out", default=None, help="JSON path (default results/..._<device>.json)")
    args = ap.parse_args()

    batches = [int(b) for b in args.batches.split(",") if b]
    backends = [b for b in args.backend.split(",") if b]
    for b in backends:
        if b not in ("mjx", "native"):
            raise SystemExit(f"error: unknown backend {b!r}; use mjx and/or native")
    if "native" in backends and jax.default_backend() != "cpu":
        print("note: native runs MuJoCo's C engine on this host's CPU threads")
    spec = load_robot(args.robot)
    k = substeps(spec, native_model(spec, 0.0, "fast"))
    control_steps = max(1, math.ceil(args.steps / k))
    steps = control_steps * k
    device = device_label()
    print(f"robot {args.robot}, device {jax.devices()[0]}, {steps} physics steps per rollout "
          f"({control_steps} control steps x {k}), {args.iterations} iteration(s) per call, "
          f"median of {args.repeats}", flush=True)

    rows = []
    header = (f"{'backend':7s} {'batch':>6s} {'colony steps/s':>15s} {'evaluate steps/s':>17s} "
              f"{'raw steps/s':>12s} {'raw walking/s':>14s} {'ratio':>6s} {'ratio wlk':>9s} "
              f"{'eval/raw':>8s} {'compile s':>9s}")
    print(header, flush=True)
    for backend in backends:
        for batch in batches:
            col = colony_rate(args.robot, backend, batch, control_steps, args.iterations,
                              args.repeats)
            if backend == "mjx":
                raw = raw_mjx_rate(args.robot, batch, control_steps, args.repeats)
                walk = raw_mjx_rate(args.robot, batch, control_steps, args.repeats, walking=True)
            else:
                raw, walk = raw_native_rate(args.robot, batch, steps, args.repeats), None
            ev = None if args.no_split else evaluate_rate(
                args.robot, backend, batch, control_steps, args.repeats)
            row = {"backend": backend, "batch": batch, "physics_steps": steps,
                   "colony_steps_per_s": col["steps_per_s"], "raw_steps_per_s": raw["steps_per_s"],
                   "ratio": col["steps_per_s"] / raw["steps_per_s"],
                   "raw_walking_steps_per_s": None if walk is None else walk["steps_per_s"],
                   "ratio_walking": None if walk is None
                   else col["steps_per_s"] / walk["steps_per_s"],
                   "evaluate_steps_per_s": None if ev is None else ev["steps_per_s"],
                   "evaluate_ratio": None if ev is None else ev["steps_per_s"] / raw["steps_per_s"],
                   "colony_wall_s": col["wall_s"], "raw_wall_s": raw["wall_s"],
                   "colony_compile_s": col["compile_s"], "raw_compile_s": raw["compile_s"]}
            rows.append(row)
            print(fmt_row(row), flush=True)

    print("\n" + header)
    for r in rows:
        print(fmt_row(r))
    native_vs_mjx = []
    by = {(r["backend"], r["batch"]): r for r in rows}
    for batch in batches:
        if ("mjx", batch) in by and ("native", batch) in by:
            n, m = by[("native", batch)], by[("mjx", batch)]
            native_vs_mjx.append({
                "batch": batch,
                "raw": n["raw_steps_per_s"] / m["raw_steps_per_s"],
                "colony": n["colony_steps_per_s"] / m["colony_steps_per_s"]})
            print(f"native / mjx at batch {batch}: raw {native_vs_mjx[-1]['raw']:.1f}x, "
                  f"colony {native_vs_mjx[-1]['colony']:.1f}x")
    record = {
        "robot": args.robot, "device": str(jax.devices()[0]), "device_label": device,
        "jax": jax.__version__, "host": platform.node(), "cpu_count": os.cpu_count(),
        "physics_steps": steps, "control_steps": control_steps, "substeps": k,
        "iterations_per_call": args.iterations, "repeats": args.repeats,
        "rows": rows, "native_vs_mjx": native_vs_mjx,
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
    }
    out = Path(args.out) if args.out else RESULTS / f"gait_throughput_{device}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
