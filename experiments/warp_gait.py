"""MJX's Warp implementation against its JAX implementation for the NAO colony (issue 13).

Sections (``--sections``, comma separated; all by default):

* ``throughput``: per implementation, batch (and, on warp, buffer size: ``--capacity-scales``
  multiples of :func:`~eaco_jax.gait.rollout_mjx.contact_capacity`), after compilation
  (median of ``--repeats``):
  **raw** ``lax.scan`` over ``vmap(mjx.step)`` fed random gaits' walk-engine targets
  (precomputed, 50 control steps by default), and **colony** ``GaitProblem.evaluate`` (walk
  engine + physics + fitness) jitted on the same random colony; compile seconds of each
  (``jit(...).lower().compile()``); ``colony / raw``.
* ``search``: seconds per iteration of the end-to-end robust search through ``ea.minimize``
  (``--search-ants`` x R = ``--search-worlds``, ``--search-horizon`` s), compile apart; and the
  plain search (R = 1) on the JAX implementation beside it.
* ``agreement``: the same gaits (``--agree-gaits`` random ones plus the search's best) over
  ``--agree-horizon`` s on warp, jax and native, in the nominal world and in randomised ones:
  distance and fall per gait, and where they differ.
* ``solver``: solver iterations x tolerance on warp: raw steps/s and the torso-position error
  after 1 s against a reference run with 100 iterations and tolerance 1e-10.

GPU (needs warp-lang; CUDA only)::

    python experiments/warp_gait.py --out $OUT/warp_gait.json

Writes JSON with the device name and versions (default ``results/gpu/warp_gait_<device>.json``).
"""

from __future__ import annotations

import argparse
import copy
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

import eaco_jax as ea
from eaco_jax.gait import rollout_mjx
from eaco_jax.gait.mjx_import import quiet_mjx
from eaco_jax.gait.rollout_mjx import contact_capacity, mjx_model
from eaco_jax.gait.rollout_native import initial_state, native_model, substeps
from eaco_jax.gait.walk_engine import stand_pose
from eaco_jax.gait.worlds import RobustConfig, couple_controls
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.strategies import ContinuousEACO

mjx = quiet_mjx()
from common import timed  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "gpu"


def log(*a: Any) -> None:
    print(*a, flush=True)


def random_gaits(problem, n: int, seed: int = 0) -> jax.Array:
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    u = np.random.default_rng(seed).random((n, lo.size))
    return jnp.asarray(lo + (hi - lo) * u, jnp.float32)


def batched_data(model: mujoco.MjModel, mm, impl: str, spec, nb: int):
    """The standing start for ``nb`` rollouts of one implementation."""
    qpos0 = jnp.asarray(initial_state(spec, model, 0.0)[1:1 + model.nq], jnp.float32)
    ctrl0 = jnp.asarray(stand_pose(spec, 0.0), jnp.float32)
    if impl == "warp":
        per_world, rows = contact_capacity(model)
        margin = rollout_mjx.CAPACITY_MARGIN
        d0 = mjx.make_data(model, impl="warp", naconmax=int(margin * per_world * nb),
                           njmax=int(margin * rows)).replace(ctrl=ctrl0)
        return jax.vmap(lambda q: mjx.forward(mm, d0.replace(qpos=q)))(
            jnp.broadcast_to(qpos0, (nb,) + qpos0.shape))
    d = mjx.forward(mm, mjx.make_data(mm).replace(qpos=qpos0, ctrl=ctrl0))
    return jax.tree.map(lambda a: jnp.broadcast_to(a, (nb,) + a.shape), d)


def raw_walking(problem, impl: str, nb: int, repeats: int, mm=None,
                model: mujoco.MjModel | None = None) -> dict[str, Any]:
    """``scan(vmap(mjx.step))`` fed precomputed walk-engine targets of ``nb`` random gaits."""
    spec = problem.spec
    model = model or native_model(spec, 0.0, "fast")
    mm = mm or mjx_model(spec, 0.0, "fast", impl)
    k = substeps(spec, model)
    controls = jax.jit(problem.controls)(random_gaits(problem, nb))
    controls = jnp.swapaxes(couple_controls(controls, spec), 0, 1)  # (T, nb, nu)
    d = batched_data(model, mm, impl, spec, nb)
    step = jax.vmap(lambda dd: mjx.step(mm, dd))

    def run(d, controls):
        def body(dd, u):
            dd = jax.lax.fori_loop(0, k, lambda _, x: step(x), dd.replace(ctrl=u))
            return dd, None

        return jax.lax.scan(body, d, controls)[0].qpos

    t0 = time.perf_counter()
    compiled = jax.jit(run).lower(d, controls).compile()
    compile_s = time.perf_counter() - t0
    first, wall = timed(lambda: compiled(d, controls), repeats)
    steps = nb * controls.shape[0] * k
    return {"compile_s": compile_s, "wall_s": wall, "steps_per_s": steps / wall}


def colony_eval(problem, nb: int, repeats: int) -> dict[str, Any]:
    """``GaitProblem.evaluate`` (walk engine, physics, fitness) jitted on ``nb`` random gaits."""
    x = random_gaits(problem, nb)
    t0 = time.perf_counter()
    compiled = jax.jit(lambda x: problem.evaluate(x).f).lower(x).compile()
    compile_s = time.perf_counter() - t0
    first, wall = timed(lambda: compiled(x), repeats)
    r = 1 if problem.robust is None else problem.robust.R
    k = substeps(problem.spec, native_model(problem.spec, 0.0, "fast"))
    steps = nb * r * problem.n_steps * k
    return {"compile_s": compile_s, "wall_s": wall, "steps_per_s": steps / wall}


def section_throughput(args) -> list[dict[str, Any]]:
    rows = []
    for impl, scale in [(i, s) for i in args.impls.split(",")
                        for s in (args.capacity_scales.split(",") if i == "warp" else ["1"])]:
        rollout_mjx.CAPACITY_MARGIN = float(scale)  # Warp buffers at this multiple of the bound
        batches = args.warp_batches if impl == "warp" else args.jax_batches
        for nb in (int(b) for b in batches.split(",")):
            p = make_gait_problem("nao", backend="mjx", horizon=args.steps * 0.02, impl=impl)
            p = p.replace(horizon=args.steps * p.spec.control_dt)
            row: dict[str, Any] = {"impl": impl, "batch": nb, "control_steps": p.n_steps}
            if impl == "warp":
                row["capacity_scale"] = float(scale)
            try:
                row["raw"] = raw_walking(p, impl, nb, args.repeats)
                row["colony"] = colony_eval(p, nb, args.repeats)
                row["colony_over_raw"] = row["colony"]["steps_per_s"] / row["raw"]["steps_per_s"]
                log(f"{impl:5s} x{scale} {nb:6d}: raw {row['raw']['steps_per_s']:12,.0f} "
                    f"colony {row['colony']['steps_per_s']:12,.0f} steps/s "
                    f"(ratio {row['colony_over_raw']:.2f}; compile raw "
                    f"{row['raw']['compile_s']:.1f} s, colony {row['colony']['compile_s']:.1f} s)")
            except Exception as err:  # noqa: BLE001 - report and go on (memory limits)
                row["error"] = f"{type(err).__name__}: {str(err).splitlines()[0][:300]}"
                log(f"{impl:5s} {nb:6d}: {row['error']}")
            rows.append(row)
    rollout_mjx.CAPACITY_MARGIN = 1.0
    return rows


def section_search(args) -> dict[str, Any]:
    out: dict[str, Any] = {}
    impls = args.impls.split(",")
    configs = [(impls[0], args.search_worlds)] + ([("jax", 1)] if "jax" in impls else [])
    for impl, r in configs:
        robust = RobustConfig(R=r) if r > 1 else None
        p = make_gait_problem("nao", backend="mjx", horizon=args.search_horizon, robust=robust,
                              impl=impl)
        ants = args.search_ants
        strategy = ContinuousEACO(num_ants=ants, archive_size=(3 * ants) // 2, refine_ants=0,
                                  repair_steps=0)
        t0 = time.perf_counter()
        res = ea.minimize(p, strategy, seed=0, iterations=args.search_iterations, chunk_size=1)
        wall = time.perf_counter() - t0
        key = f"{impl}_R{r}"
        out[key] = {"ants": ants, "R": r, "horizon_s": args.search_horizon,
                    "iterations": res.iterations, "compile_s": res.compile_seconds,
                    "seconds_per_iteration": res.seconds_per_iteration, "wall_s": wall,
                    "best_fitness": float(-res.best_cost),
                    "best_vector": np.asarray(res.best_solution).tolist()}
        log(f"search {key}: {res.seconds_per_iteration:.2f} s/iteration "
            f"(compile {res.compile_seconds:.1f} s), best {float(-res.best_cost):.3f} m")
    return out


def section_agreement(args, extra: list[np.ndarray]) -> dict[str, Any]:
    p = make_gait_problem("nao", backend="mjx", horizon=args.agree_horizon, impl="jax")
    gaits = np.asarray(random_gaits(p, args.agree_gaits, seed=1))
    if extra:
        gaits = np.concatenate([gaits, np.asarray(extra, np.float32)], 0)
    x = jnp.asarray(gaits)
    out: dict[str, Any] = {"gaits": int(len(gaits)), "horizon_s": args.agree_horizon}
    for label, robust in (("nominal", None), ("randomised", RobustConfig(R=4, seed=7))):
        res = {}
        runs = [("mjx", i) for i in args.impls.split(",")] + [("native", "jax")]
        for backend, impl in runs:
            q = make_gait_problem("nao", backend=backend, horizon=args.agree_horizon,
                                  robust=robust, impl=impl)
            worlds = None if robust is None else q.worlds()
            r = jax.jit(lambda x, q=q, w=worlds: q.rollout(x, w))(x)
            name = "native" if backend == "native" else f"{backend}-{impl}"
            res[name] = {k: np.asarray(r[k]) for k in ("distance_m", "fell")}
        ref = res["native"]  # the reference row (files before 2026-11-23 call it native-jax)
        table = {}
        for name, r in res.items():
            dd = np.abs(r["distance_m"] - ref["distance_m"])
            table[name] = {
                "mean_abs_distance_diff_m": float(dd.mean()),
                "max_abs_distance_diff_m": float(dd.max()),
                "fall_agreement": float(np.mean(r["fell"] == ref["fell"])),
                "falls": int(np.sum(r["fell"])),
            }
        out[label] = table
        log(f"agreement {label}: " + "; ".join(
            f"{k}: |dd| mean {v['mean_abs_distance_diff_m']:.3f} max "
            f"{v['max_abs_distance_diff_m']:.3f} m, falls {v['falls']}, fall agree "
            f"{v['fall_agreement']:.2f}" for k, v in table.items()))
    return out


def section_solver(args) -> list[dict[str, Any]]:
    p = make_gait_problem("nao", backend="mjx", horizon=1.0, impl="warp")
    spec = p.spec
    base = native_model(spec, 0.0, "fast")
    nb = args.solver_batch
    rows = []
    ref_pos = None
    settings = [(100, 1e-10)] + [(i, t) for i in (2, 4, 8, 16) for t in (1e-6,)]
    for iters, tol in settings:
        model = copy.copy(base)
        model.opt.iterations = iters
        model.opt.tolerance = tol
        mm = mjx.put_model(model, impl="warp")
        rate = raw_walking(p, "warp", nb, args.repeats, mm=mm, model=model)
        controls = jax.jit(p.controls)(random_gaits(p, nb))
        controls = jnp.swapaxes(couple_controls(controls, spec), 0, 1)
        d = batched_data(model, mm, "warp", spec, nb)
        step = jax.vmap(lambda dd, mm=mm: mjx.step(mm, dd))
        k = substeps(spec, model)

        def run(d, controls, step=step, k=k):
            def body(dd, u):
                return jax.lax.fori_loop(0, k, lambda _, x: step(x), dd.replace(ctrl=u)), None

            return jax.lax.scan(body, d, controls)[0].qpos[:, :3]

        pos = np.asarray(jax.jit(run)(d, controls))
        if ref_pos is None:
            ref_pos = pos
        err = np.linalg.norm(pos - ref_pos, axis=1)
        row = {"iterations": iters, "tolerance": tol, "steps_per_s": rate["steps_per_s"],
               "torso_err_mean_mm": float(1e3 * err.mean()),
               "torso_err_p95_mm": float(1e3 * np.percentile(err, 95))}
        rows.append(row)
        log(f"solver it={iters:3d} tol={tol:g}: {rate['steps_per_s']:12,.0f} steps/s, torso "
            f"error after 1 s mean {row['torso_err_mean_mm']:.2f} mm, p95 "
            f"{row['torso_err_p95_mm']:.2f} mm")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", default="throughput,search,agreement,solver")
    ap.add_argument("--impls", default="warp,jax")
    ap.add_argument("--warp-batches", default="4096,16384,32768,65536")
    ap.add_argument("--jax-batches", default="4096,16384")
    ap.add_argument("--steps", type=int, default=50, help="control steps (throughput)")
    ap.add_argument("--capacity-scales", default="1",
                    help="Warp buffers at these multiples of the exact bound (throughput)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--search-ants", type=int, default=4096)
    ap.add_argument("--search-worlds", type=int, default=8)
    ap.add_argument("--search-horizon", type=float, default=20.0)
    ap.add_argument("--search-iterations", type=int, default=3)
    ap.add_argument("--agree-gaits", type=int, default=64)
    ap.add_argument("--agree-horizon", type=float, default=20.0)
    ap.add_argument("--solver-batch", type=int, default=4096)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    device = jax.devices()[0].device_kind if jax.default_backend() != "cpu" else "cpu"
    record: dict[str, Any] = {
        "device": device, "jax": jax.__version__, "mujoco": mujoco.__version__,
        "python": platform.python_version(), "argv": sys.argv[1:],
        "capacity_per_world": contact_capacity(native_model(
            make_gait_problem("nao", backend="native").spec, 0.0, "fast")),
    }
    try:
        import warp

        record["warp"] = warp.config.version
    except ImportError:
        record["warp"] = None
    out = Path(args.out or RESULTS / f"warp_gait_{device.replace(' ', '_').lower()}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    sections = args.sections.split(",")

    def save() -> None:
        out.write_text(json.dumps(record, indent=1, default=float) + "\n")

    if "throughput" in sections:
        record["throughput"] = section_throughput(args)
        save()
    best = []
    if "search" in sections:
        record["search"] = section_search(args)
        best = [np.asarray(v["best_vector"]) for v in record["search"].values()]
        save()
    if "agreement" in sections:
        record["agreement"] = section_agreement(args, best)
        save()
    if "solver" in sections:
        record["solver"] = section_solver(args)
        save()
    log(f"wrote {out}")


if __name__ == "__main__":
    main()
