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

Every rate is physics steps x ants x worlds (``--worlds`` R randomised worlds per ant, the robust
fitness's) / wall seconds, compilation excluded and reported apart (``compile s``). The raw loops
step ants x worlds copies. ``--robot`` takes several robots (``nao,op3,go2``: shipped names or
spec paths) for MJX steps/s per robot side by side; ``--impl`` picks MJX's implementation
(``jax``, ``warp`` on CUDA: the raw loops are then not timed, ``auto``).

``--constrained`` times the constrained search's problem instead (``eaco gait --constrained``:
speed under the endurance, current, slip, drift and fall constraints, each computed in the same
batched rollout, the motors' thermal model included), beside the same raw rate.

``ratio = colony / raw`` is what the optimiser (controller, fitness, colony) costs; the target is
>= 0.9. ``ratio wlk = colony / raw walking`` separates the optimiser's own cost from the harder
physics of walking robots. ``eval/raw`` shows how much of that is the walk engine rather than
ask/tell. On CPU it also prints native against MJX at the same batch.

CPU (default)::

    python experiments/gait_throughput.py --batches 32,64,128 --backend mjx,native --steps 250

GPU (through ``device``)::

    python experiments/gait_throughput.py --batches 1024,4096,16384 --backend mjx --steps 1000

Per robot, the robust search's shape, on a GPU with MuJoCo Warp (any folder, an installed
eaco_jax; the script needs only ``experiments/common.py`` beside it)::

    python experiments/gait_throughput.py --robot nao,op3,go2 --backend mjx --impl warp \
        --batches 2048 --worlds 8 --steps 500 --no-split --out $OUT/gait_throughput_robots.json

Writes ``experiments/results/gait_throughput_<device>.json`` unless ``--out`` names a file.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from common import device_info, timed

import eaco_jax as ea
from eaco_jax.errors import ProblemError
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.rollout_mjx import mjx_model
from eaco_jax.gait.rollout_native import initial_state, native_model, substeps
from eaco_jax.gait.steer import Steering
from eaco_jax.gait.worlds import RobustConfig
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.strategies.continuous_eaco import ContinuousEACO

RESULTS = Path(__file__).resolve().parent / "results"


def gait_problem(robot: str, backend: str, control_steps: int, worlds: int = 1,
                 impl: str = "auto", constrained: bool = False, steer: bool = False):
    """The gait problem timed: ``control_steps`` long, R = ``worlds`` randomised worlds per ant
    (the robust fitness; seed 0 of the optimisation stream) when ``worlds`` > 1;
    ``constrained``: the constrained search's problem (speed under the motor, slip, drift and
    fall constraints, computed in the same rollout); ``steer``: with the heading feedback of
    :mod:`eaco_jax.gait.steer` (its defaults)."""
    spec = load_robot(robot)
    robust = RobustConfig(R=int(worlds), seed=0) if worlds > 1 else None
    kw = {"impl": impl} if backend == "mjx" else {}
    problem = make_gait_problem(robot, backend=backend, horizon=control_steps * spec.control_dt,
                                robust=robust, constrained=constrained,
                                steering=Steering() if steer else None, **kw)
    assert problem.n_steps == control_steps
    return problem


def colony_rate(robot: str, backend: str, batch: int, control_steps: int, iterations: int,
                repeats: int, seed: int = 0, worlds: int = 1,
                impl: str = "auto", constrained: bool = False,
                steer: bool = False) -> dict[str, Any]:
    """Physics steps/s of the jitted colony loop (ask, batched rollout + fitness, tell):
    physics steps x ants x worlds x iterations / wall seconds."""
    spec = load_robot(robot)
    k = substeps(spec, native_model(spec, 0.0, "fast"))
    problem = gait_problem(robot, backend, control_steps, worlds, impl, constrained,
                           steer)
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
            "steps_per_s": steps * batch * worlds * iterations / wall,
            "best_fitness": -float(np.asarray(best.best_cost)), "impl": problem.impl}


def evaluate_rate(robot: str, backend: str, batch: int, control_steps: int, repeats: int,
                  seed: int = 0, worlds: int = 1, impl: str = "auto",
                  constrained: bool = False, steer: bool = False) -> dict[str, Any]:
    """Physics steps/s of ``GaitProblem.evaluate`` alone (walk engine + physics + fitness, no
    colony): separates what the controller costs from what the colony update costs."""
    spec = load_robot(robot)
    k = substeps(spec, native_model(spec, 0.0, "fast"))
    problem = gait_problem(robot, backend, control_steps, worlds, impl, constrained,
                           steer)
    x = random_gaits(problem, batch, seed)
    t0 = time.perf_counter()
    fn = jax.jit(lambda a: problem.evaluate(a)).lower(x).compile()
    compile_s = time.perf_counter() - t0
    _, wall = timed(lambda: fn(x), repeats)
    steps = control_steps * k
    return {"compile_s": compile_s, "wall_s": wall,
            "steps_per_s": steps * batch * worlds / wall}


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


HEADER = (f"{'robot':8s} {'backend':9s} {'batch':>6s} {'R':>3s} {'colony steps/s':>15s} "
          f"{'evaluate steps/s':>17s} {'raw steps/s':>12s} {'raw walking/s':>14s} "
          f"{'ratio':>6s} {'ratio wlk':>9s} {'eval/raw':>8s} {'compile s':>9s}")


def fmt_row(r: dict[str, Any]) -> str:
    backend = r["backend"] if r["backend"] != "mjx" else f"mjx-{r['impl']}"
    return (f"{r['robot'][:8]:8s} {backend:9s} {r['batch']:6d} {r['worlds']:3d} "
            f"{r['colony_steps_per_s']:15,.0f} "
            f"{_opt(r['evaluate_steps_per_s'], ',.0f', 17)} "
            f"{_opt(r['raw_steps_per_s'], ',.0f', 12)} "
            f"{_opt(r['raw_walking_steps_per_s'], ',.0f', 14)} {_opt(r['ratio'], '.2f', 6)} "
            f"{_opt(r['ratio_walking'], '.2f', 9)} {_opt(r['evaluate_ratio'], '.2f', 8)} "
            f"{r['colony_compile_s']:9.1f}")


def device_label() -> str:
    dev = jax.devices()[0]
    kind = dev.platform if dev.platform == "cpu" else getattr(dev, "device_kind", dev.platform)
    return re.sub(r"[^a-z0-9]+", "_", str(kind).lower()).strip("_")


def ratio(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None else a / b


def measure(robot: str, backend: str, batch: int, args: argparse.Namespace) -> dict[str, Any]:
    """One row: colony (and evaluate, raw, raw walking) steps/s of ``robot`` at ``batch`` ants
    x ``args.worlds`` worlds, compile seconds apart."""
    spec = load_robot(robot)
    k = substeps(spec, native_model(spec, 0.0, "fast"))
    control_steps = max(1, math.ceil(args.steps / k))
    steps = control_steps * k
    copies = batch * args.worlds
    col = colony_rate(robot, backend, batch, control_steps, args.iterations, args.repeats,
                      worlds=args.worlds, impl=args.impl, constrained=args.constrained,
                      steer=args.steer)
    impl = col["impl"] if backend == "mjx" else "c"
    raw = walk = None
    if args.no_raw:
        pass
    elif backend == "mjx" and impl == "jax":
        raw = raw_mjx_rate(robot, copies, control_steps, args.repeats)
        walk = raw_mjx_rate(robot, copies, control_steps, args.repeats, walking=True)
    elif backend == "native":
        raw = raw_native_rate(robot, copies, steps, args.repeats)
    ev = None if args.no_split else evaluate_rate(
        robot, backend, batch, control_steps, args.repeats, worlds=args.worlds, impl=args.impl,
        constrained=args.constrained, steer=args.steer)
    rate = lambda d: None if d is None else d["steps_per_s"]  # noqa: E731
    return {"robot": spec.name, "backend": backend, "impl": impl, "batch": batch,
            "worlds": args.worlds, "constrained": args.constrained, "steer": args.steer,
            "physics_steps": steps,
            "control_steps": control_steps,
            "substeps": k, "timestep_s": spec.control_dt / k,
            "colony_steps_per_s": col["steps_per_s"], "raw_steps_per_s": rate(raw),
            "ratio": ratio(col["steps_per_s"], rate(raw)),
            "raw_walking_steps_per_s": rate(walk),
            "ratio_walking": ratio(col["steps_per_s"], rate(walk)),
            "evaluate_steps_per_s": rate(ev), "evaluate_ratio": ratio(rate(ev), rate(raw)),
            "colony_wall_s": col["wall_s"], "raw_wall_s": None if raw is None else raw["wall_s"],
            "colony_compile_s": col["compile_s"],
            "evaluate_compile_s": None if ev is None else ev["compile_s"],
            "raw_compile_s": None if raw is None else raw["compile_s"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="nao",
                    help="robot(s), comma separated: shipped names (nao, op3, go2) or spec paths")
    ap.add_argument("--batches", default="32,64,128", help="colony sizes, comma separated")
    ap.add_argument("--backend", default="mjx,native", help="mjx, native or both")
    ap.add_argument("--impl", default="jax", choices=("jax", "warp", "auto"),
                    help="MJX implementation (warp: CUDA only; the raw loops are not timed)")
    ap.add_argument("--worlds", type=int, default=1,
                    help="randomised worlds per ant (the robust fitness's R); 1 = nominal world")
    ap.add_argument("--steps", type=int, default=250,
                    help="physics steps per rollout (rounded up to whole control steps)")
    ap.add_argument("--iterations", type=int, default=1, help="colony iterations per call")
    ap.add_argument("--repeats", type=int, default=3, help="timed calls (median)")
    ap.add_argument("--no-split", action="store_true",
                    help="skip timing GaitProblem.evaluate alone (one compile less per batch)")
    ap.add_argument("--no-raw", action="store_true",
                    help="skip the raw physics loops (two compiles less per MJX batch)")
    ap.add_argument("--constrained", action="store_true",
                    help="time the constrained search's problem (eaco gait --constrained: "
                         "thermal, current, slip, drift and fall constraints in the rollout)")
    ap.add_argument("--steer", action="store_true",
                    help="with the heading feedback of eaco gait --steer (its defaults)")
    ap.add_argument("--out", default=None, help="JSON path (default results/..._<device>.json)")
    args = ap.parse_args()

    robots = [r for r in args.robot.split(",") if r]
    batches = [int(b) for b in args.batches.split(",") if b]
    backends = [b for b in args.backend.split(",") if b]
    for b in backends:
        if b not in ("mjx", "native"):
            raise SystemExit(f"error: unknown backend {b!r}; use mjx and/or native")
    if args.worlds < 1 or not batches or min(batches) < 1:
        raise SystemExit("error: --worlds and every --batches entry must be positive integers")
    try:
        for r in robots:
            load_robot(r)
    except ProblemError as err:
        raise SystemExit(f"error: {err}") from None
    if "native" in backends and jax.default_backend() != "cpu":
        print("note: native runs MuJoCo's C engine on this host's CPU threads")
    device = device_label()
    print(f"robots {', '.join(robots)}, device {jax.devices()[0]}, {args.steps} physics steps "
          f"per rollout (rounded up to whole control steps), {args.worlds} world(s) per ant, "
          f"{args.iterations} iteration(s) per call, median of {args.repeats}; steps/s = "
          "physics steps x ants x worlds / wall seconds, compilation apart", flush=True)

    rows = []
    print(HEADER, flush=True)
    for robot in robots:
        for backend in backends:
            for batch in batches:
                row = measure(robot, backend, batch, args)
                rows.append(row)
                print(fmt_row(row), flush=True)

    print("\n" + HEADER)
    for r in rows:
        print(fmt_row(r))
    native_vs_mjx = []
    by = {(r["robot"], r["backend"], r["batch"]): r for r in rows}
    for robot in {r["robot"] for r in rows}:
        for batch in batches:
            n, m = by.get((robot, "native", batch)), by.get((robot, "mjx", batch))
            if n is None or m is None:
                continue
            native_vs_mjx.append({"robot": robot, "batch": batch,
                                  "raw": ratio(n["raw_steps_per_s"], m["raw_steps_per_s"]),
                                  "colony": n["colony_steps_per_s"] / m["colony_steps_per_s"]})
            print(f"{robot} native / mjx at batch {batch}: colony "
                  f"{native_vs_mjx[-1]['colony']:.1f}x")
    record = {
        "robot": args.robot, "robots": robots, "device": str(jax.devices()[0]),
        "device_label": device, "info": device_info(), "jax": jax.__version__,
        "mujoco": mujoco_version(), "eaco_jax": ea.__version__,
        "host": platform.node(), "cpu_count": os.cpu_count(),
        "command": "python experiments/gait_throughput.py " + " ".join(sys.argv[1:]),
        "date": time.strftime("%Y-%m-%d"), "worlds": args.worlds, "impl": args.impl,
        "constrained": args.constrained, "steer": args.steer,
        "steps_requested": args.steps, "iterations_per_call": args.iterations,
        "repeats": args.repeats, "rows": rows, "native_vs_mjx": native_vs_mjx,
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
    }
    out = Path(args.out) if args.out else RESULTS / f"gait_throughput_{device}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {out}")


def mujoco_version() -> str:
    import mujoco

    return mujoco.__version__


if __name__ == "__main__":
    main()
