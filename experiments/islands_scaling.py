"""Islands over devices: throughput scaling, device agreement, islands vs one colony (issue 16).

Parts (``--parts``, default all):

* ``gait``: NAO gait evaluation (MJX) on the first 1..N devices
  (:func:`eaco_jax.problems.sharding.shard`), at fixed work per device (weak: batch =
  ``--gait-per-device`` x devices) and fixed total work (strong: ``--gait-total``), physics
  steps/s, weak-scaling efficiency and strong speed-up.
* ``agree``: the same ants' fitness on 1 device against N devices: max |df|, how many ants
  differ at all / by more than 1 mm, and how many of those are a fall or threshold flip (one of
  the two fitness values is 0). Variants: default, ``jax_default_matmul_precision=highest`` (no
  TF32), and evaluation in fixed blocks (every device runs the same block program).
* ``tsp``: TSP iterations/s of ``Islands(GraphEACO(m), C, shard=True, num_devices=D)``, weak
  (C = ``--islands-per-device`` x D) and strong (C = ``--islands-total``), and of one colony of
  C x m ants with its evaluation split over the same devices.
* ``quality``: islands against one colony of the same total size (C x m ants): TSP instances
  (``--tsp-instances``) at fixed wall time per seed group, CEC2006 problems
  (``--cec-problems``) at fixed evaluations (float64), optionally the NAO gait at fixed
  rollouts (``--gait-quality``); ``--seeds`` seeds, vmapped per call; mean, 95% CI of the mean,
  and the Welch 95% CI of the difference (islands - one colony; below 0 = islands better).

CPU smoke run (forced host devices; timings there say nothing about GPUs)::

    python experiments/islands_scaling.py --cpu-devices 4 --quick

GPU (the lead, through ``device``; writes ``experiments/results/islands_scaling_<kind>.json``)::

    python experiments/islands_scaling.py --parts gait,agree,tsp          # on 1 and on 2 GPUs
    python experiments/islands_scaling.py --parts quality --seeds 25

Every record carries the device kind and count, the versions and the command line.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"


# --------------------------------------------------------------------------- helpers
def environment() -> dict[str, Any]:
    """Device kind and count, versions, flags: what a timing needs to be compared."""
    import jax
    import jaxlib
    import numpy as np

    import eaco_jax

    try:
        import mujoco
        mujoco_version = mujoco.__version__
    except ImportError:  # pragma: no cover
        mujoco_version = None
    dev = jax.devices()
    return {
        "device_kind": dev[0].device_kind, "platform": dev[0].platform, "devices": len(dev),
        "processes": jax.process_count(), "jax": jax.__version__, "jaxlib": jaxlib.__version__,
        "mujoco": mujoco_version, "eaco_jax": eaco_jax.__version__, "numpy": np.__version__,
        "python": platform.python_version(), "host": platform.node(),
        "cpu_count": os.cpu_count(), "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "command": "python " + " ".join(sys.argv),
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def device_counts(limit: int | None) -> list[int]:
    """1, 2, 4, ... up to every device (and every device itself)."""
    import jax

    n = len(jax.devices()) if limit is None else min(limit, len(jax.devices()))
    counts = [1 << i for i in range(n.bit_length()) if 1 << i <= n]
    return counts + ([n] if counts[-1] != n else [])


def timed(fn, *args, repeats: int = 3) -> tuple[Any, float, float]:
    """(output, first-call seconds incl. compile, median seconds of ``repeats`` calls)."""
    import jax
    import numpy as np

    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t0
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        walls.append(time.perf_counter() - t0)
    return out, first, float(np.median(walls))


def mean_ci(values: list[float]) -> dict[str, float]:
    """Mean, standard deviation and the 95% t-interval of the mean."""
    import numpy as np
    from scipy import stats

    a = np.asarray(values, np.float64)
    n = len(a)
    sd = float(a.std(ddof=1)) if n > 1 else 0.0
    half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else float("nan")
    return {"n": n, "mean": float(a.mean()), "sd": sd, "ci95": [a.mean() - half, a.mean() + half],
            "median": float(np.median(a)), "min": float(a.min()), "max": float(a.max())}


def welch_diff(a: list[float], b: list[float]) -> dict[str, float]:
    """mean(a) - mean(b) with Welch's 95% interval, and the Mann-Whitney two-sided p."""
    import numpy as np
    from scipy import stats

    x, y = np.asarray(a, np.float64), np.asarray(b, np.float64)
    d = float(x.mean() - y.mean())
    vx, vy = x.var(ddof=1) / len(x), y.var(ddof=1) / len(y)
    se = math.sqrt(vx + vy)
    if se == 0:
        return {"diff": d, "ci95": [d, d], "mannwhitney_p": 1.0}
    dof = (vx + vy) ** 2 / (vx**2 / (len(x) - 1) + vy**2 / (len(y) - 1))
    half = float(stats.t.ppf(0.975, dof) * se)
    p = float(stats.mannwhitneyu(x, y, alternative="two-sided").pvalue)
    return {"diff": d, "ci95": [d - half, d + half], "mannwhitney_p": p}


def blocked_evaluate(problem, devices, block: int):
    """``problem.evaluate`` in blocks of ``block`` ants, each device mapping over its blocks:
    every device runs the same block program whatever the device count (an experiment on
    whether that makes the devices agree; not the library's default)."""
    import jax
    import jax.numpy as jnp
    import numpy as np
    from jax.sharding import Mesh, NamedSharding
    from jax.sharding import PartitionSpec as P

    mesh = Mesh(np.array(devices), ("ants",))

    def evaluate(x):
        n, d = x.shape[0], len(devices)
        per = -(-n // (d * block))
        pad = d * per * block - n
        x = jnp.concatenate([x, jnp.broadcast_to(x[:1], (pad, *x.shape[1:]))])
        x = jax.lax.with_sharding_constraint(x.reshape(d, per, block, *x.shape[1:]),
                                             NamedSharding(mesh, P("ants")))
        f = jax.vmap(lambda xd: jax.lax.map(lambda b: problem.evaluate(b).f, xd))(x)
        return f.reshape(-1)[:n]

    return evaluate


def sharded_f(problem):
    """The objective of a (sharded) problem's evaluation, for jit."""
    return lambda x: problem.evaluate(x).f


# --------------------------------------------------------------------------- parts
def gait_problem(args):
    from eaco_jax.problems.gait import make_gait_problem

    return make_gait_problem("nao", backend="mjx", horizon=args.gait_horizon)


def random_gaits(problem, n: int, seed: int = 0):
    import jax.numpy as jnp
    import numpy as np

    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    rng = np.random.default_rng(seed)
    return jnp.asarray(lo + (hi - lo) * rng.random((n, problem.dim)), jnp.float32)


def part_gait(args) -> list[dict]:
    """Weak and strong scaling of sharded gait evaluation."""
    import jax

    from eaco_jax.gait.rollout_native import native_model, substeps
    from eaco_jax.problems.sharding import shard

    problem = gait_problem(args)
    steps = problem.n_steps * substeps(problem.spec, native_model(problem.spec, 0.0, "fast"))
    rows, base = [], {}
    for mode in ("weak", "strong"):
        for d in device_counts(args.max_devices):
            batch = args.gait_per_device * d if mode == "weak" else args.gait_total
            x = random_gaits(problem, batch)
            prob = shard(problem, jax.devices()[:d])
            _, first, wall = timed(jax.jit(sharded_f(prob)), x, repeats=args.repeats)
            rate = steps * batch / wall
            base.setdefault(mode, rate)
            row = {"part": "gait", "mode": mode, "devices": d, "batch": batch,
                   "physics_steps": steps, "wall_s": wall, "first_call_s": first,
                   "steps_per_s": rate, "speedup": rate / base[mode],
                   "efficiency": rate / base[mode] / d}
            rows.append(row)
            print(f"gait {mode:>6} {d:>2} dev batch {batch:>6}: {rate:14,.0f} steps/s "
                  f"x{row['speedup']:.2f} (eff {row['efficiency']:.2f})", flush=True)
    return rows


def part_agree(args) -> list[dict]:
    """The same ants on 1 device and on all devices: how far apart, and why."""
    import jax
    import numpy as np

    from eaco_jax.problems.sharding import shard

    problem = gait_problem(args)
    devices = jax.devices()
    x = random_gaits(problem, args.gait_total, seed=1)
    rows = []
    variants = [("default", None, False), ("highest", "highest", False),
                ("blocks", None, True), ("blocks+highest", "highest", True)]
    for name, precision, blocks in variants:
        with jax.default_matmul_precision(precision):
            out = {}
            for d in sorted({1, len(devices)}):
                if blocks:
                    fn = blocked_evaluate(problem, devices[:d], args.agree_block)
                else:
                    fn = sharded_f(shard(problem, devices[:d]))
                out[d] = np.asarray(jax.jit(fn)(x), np.float64)
        one, many = out[1], out[len(devices)]
        diff = np.abs(one - many)
        flips = (diff > 1e-3) & ((one == 0) | (many == 0))
        row = {"part": "agree", "variant": name, "devices": len(devices), "ants": len(x),
               "max_abs_diff_m": float(diff.max()), "ants_differing": int((diff > 0).sum()),
               "ants_over_1mm": int((diff > 1e-3).sum()), "threshold_flips": int(flips.sum()),
               "max_abs_diff_without_flips_m": float(np.where(flips, 0, diff).max()),
               "top_diffs": [[float(one[i]), float(many[i])]
                             for i in np.argsort(-diff)[:5]]}
        rows.append(row)
        print(f"agree {name:>15}: max |df| {row['max_abs_diff_m']:.3e} m, "
              f"{row['ants_differing']} ants differ, {row['ants_over_1mm']} by > 1 mm, "
              f"{row['threshold_flips']} flips", flush=True)
    return rows


def part_tsp(args) -> list[dict]:
    """Iterations/s of sharded islands (weak, strong) and of one colony split by evaluation."""
    import jax

    import eaco_jax as ea
    from eaco_jax.problems.sharding import shard
    from eaco_jax.problems.tsp import load_tsplib
    from eaco_jax.strategies import GraphEACO
    from eaco_jax.strategies.islands import Islands

    problem = load_tsplib(args.tsp_speed_instance)
    inner = GraphEACO(num_ants=args.ants_per_island)
    rows, base = [], {}
    for mode in ("weak", "strong", "one-colony"):
        for d in device_counts(args.max_devices):
            c = args.islands_per_device * d if mode == "weak" else args.islands_total
            if mode == "one-colony":
                strategy = GraphEACO(num_ants=c * args.ants_per_island)
                prob = shard(problem, jax.devices()[:d])
            else:
                strategy = Islands(inner, islands=c, every=10, shard=True, num_devices=d)
                prob = problem
            res = ea.minimize(prob, strategy, seed=0, iterations=2 * args.tsp_chunk,
                              chunk_size=args.tsp_chunk)
            per_it = res.seconds_per_iteration
            ants_per_s = strategy.num_ants / per_it
            base.setdefault(mode, ants_per_s)
            row = {"part": "tsp", "mode": mode, "devices": d, "instance": problem.name,
                   "islands": None if mode == "one-colony" else c,
                   "ants": strategy.num_ants, "seconds_per_iteration": per_it,
                   "tours_per_s": ants_per_s, "speedup": ants_per_s / base[mode],
                   "efficiency": ants_per_s / base[mode] / d,
                   "compile_s": res.compile_seconds}
            rows.append(row)
            print(f"tsp {mode:>10} {d:>2} dev {strategy.num_ants:>6} ants: "
                  f"{per_it * 1e3:9.2f} ms/it, {ants_per_s:12,.0f} tours/s "
                  f"x{row['speedup']:.2f} (eff {row['efficiency']:.2f})", flush=True)
    return rows


def _quality_pair(inner_cls, inner_kw: dict, args) -> list[tuple[str, Any]]:
    """(one colony of C x m ants, C islands of m ants): the same total colony size."""
    import jax

    from eaco_jax.strategies.islands import Islands

    one = inner_cls(num_ants=args.islands * args.ants_per_island, **inner_kw)
    isl = Islands(inner_cls(num_ants=args.ants_per_island, **inner_kw), islands=args.islands,
                  every=args.every, migrants=args.migrants, topology=args.topology,
                  replace=args.replace, shard=len(jax.devices()) > 1)
    return [("one-colony", one), ("islands", isl)]


def part_quality(args) -> list[dict]:
    """Islands vs one colony of the same total size: TSP at fixed wall time, CEC2006 at
    fixed evaluations, the NAO gait at fixed rollouts."""
    import numpy as np

    import eaco_jax as ea
    from eaco_jax.problems import cec2006, float64
    from eaco_jax.problems.tsp import load_tsplib, tour_length
    from eaco_jax.strategies import ContinuousEACO, GraphEACO

    seeds = list(range(args.seeds))
    groups = [seeds[i:i + args.group] for i in range(0, len(seeds), args.group)]
    rows = []

    def record(kind, name, label, strategy, values, extra):
        row = {"part": "quality", "kind": kind, "problem": name, "config": label,
               "strategy": repr(strategy), "values": values, "stats": mean_ci(values), **extra}
        rows.append(row)
        s = row["stats"]
        print(f"{name:>8} {label:>10}: mean {s['mean']:.6g} CI [{s['ci95'][0]:.6g}, "
              f"{s['ci95'][1]:.6g}] (n={s['n']})", flush=True)

    def compare(name, metric):
        pair = [r for r in rows if r["problem"] == name]
        d = welch_diff(pair[1]["values"], pair[0]["values"])
        rows.append({"part": "quality", "problem": name, "config": "islands - one-colony",
                     "metric": metric, **d})
        print(f"{name:>8} islands - one: {d['diff']:.4g} CI [{d['ci95'][0]:.4g}, "
              f"{d['ci95'][1]:.4g}], Mann-Whitney p {d['mannwhitney_p']:.3g}", flush=True)

    for name in args.tsp_instances:
        problem = load_tsplib(name)
        for label, strategy in _quality_pair(GraphEACO, {"local_search": args.tsp_ls}, args):
            gaps, iters = [], []
            for g in groups:
                budget = ({"iterations": args.tsp_iterations} if args.tsp_iterations else
                          {"iterations": 10**9, "max_seconds": args.tsp_seconds})
                res = ea.minimize(problem, strategy, seed=g, chunk_size=args.tsp_chunk,
                                  **budget)
                tours = np.asarray(res.best_solution).reshape(len(g), -1)
                lengths = [tour_length(np.asarray(problem.dist), t) for t in tours]
                gaps += [100.0 * (length / problem.optimum - 1.0) for length in lengths]
                iters.append(int(res.iterations))
            record("tsp", name, label, strategy, gaps,
                   {"metric": "gap_percent", "iterations_budget": args.tsp_iterations,
                    "seconds_per_group": None if args.tsp_iterations else args.tsp_seconds,
                    "group": args.group, "iterations_per_group": iters})
        compare(name, "gap_percent")

    for name in args.cec_problems:
        with float64():
            problem = cec2006(name)
            for label, strategy in _quality_pair(ContinuousEACO, {}, args):
                errors, evals = [], []
                for g in groups:
                    res = ea.minimize(problem, strategy, seed=g, chunk_size=50,
                                      max_evaluations=args.cec_evaluations,
                                      stop=ea.stop.Evaluations(args.cec_evaluations))
                    f = np.atleast_1d(np.asarray(res.f, np.float64))
                    feasible = np.atleast_1d(res.feasible)
                    errors += np.where(feasible, f - problem.f_star, np.inf).tolist()
                    evals += np.atleast_1d(res.evaluations).tolist()
                finite = [e for e in errors if math.isfinite(e)]
                record("cec2006", name, label, strategy, finite,
                       {"metric": "f - f*", "infeasible_runs": len(errors) - len(finite),
                        "successes": int(sum(e <= 1e-4 for e in finite)),
                        "evaluations": evals, "budget": args.cec_evaluations})
        compare(name, "f - f*")

    if args.gait_quality:
        problem = gait_problem(args)
        kw = {"refine_ants": 0, "repair_steps": 0}
        for label, strategy in _quality_pair(ContinuousEACO, kw, args):
            fitness = []
            for g in groups:
                res = ea.minimize(problem, strategy, seed=g, max_evaluations=args.gait_rollouts,
                                  chunk_size=10)
                fitness += (-np.atleast_1d(np.asarray(res.f, np.float64))).tolist()
            record("gait", "nao", label, strategy, fitness,
                   {"metric": "fitness_m", "rollouts": args.gait_rollouts})
        compare("nao", "fitness_m")
    return rows


# --------------------------------------------------------------------------- main
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="gait,agree,tsp,quality")
    ap.add_argument("--quick", action="store_true", help="tiny sizes (CPU smoke run)")
    ap.add_argument("--cpu-devices", type=int, default=None,
                    help="force this many host devices (sets XLA_FLAGS before JAX starts)")
    ap.add_argument("--max-devices", type=int, default=None)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--gait-horizon", type=float, default=1.0)
    ap.add_argument("--gait-per-device", type=int, default=4096)
    ap.add_argument("--gait-total", type=int, default=8192)
    ap.add_argument("--agree-block", type=int, default=4096)
    ap.add_argument("--tsp-speed-instance", default="pcb442")
    ap.add_argument("--islands-per-device", type=int, default=8)
    ap.add_argument("--islands-total", type=int, default=16)
    ap.add_argument("--tsp-chunk", type=int, default=10)
    ap.add_argument("--islands", type=int, default=8, help="quality: islands C")
    ap.add_argument("--ants-per-island", type=int, default=40, help="m (one colony: C x m)")
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--migrants", type=int, default=1)
    ap.add_argument("--topology", default="ring", choices=["ring", "all", "random"])
    ap.add_argument("--replace", default="worst", choices=["worst", "random"])
    ap.add_argument("--seeds", type=int, default=25)
    ap.add_argument("--group", type=int, default=5, help="seeds per vmapped call")
    ap.add_argument("--tsp-instances", default="pcb442,pr1002")
    ap.add_argument("--tsp-seconds", type=float, default=60.0,
                    help="wall seconds per group of seeds (compilation excluded)")
    ap.add_argument("--tsp-iterations", type=int, default=None,
                    help="fixed iterations (= evaluations) instead of --tsp-seconds")
    ap.add_argument("--tsp-ls", default="2opt", choices=["2opt", "none"],
                    help="quality: GraphEACO local search")
    ap.add_argument("--cec-problems", default="g10,g13")
    ap.add_argument("--cec-evaluations", type=int, default=200_000)
    ap.add_argument("--gait-quality", action="store_true")
    ap.add_argument("--gait-rollouts", type=int, default=100_000)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    if args.cpu_devices:
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") +
                                   f" --xla_force_host_platform_device_count={args.cpu_devices}")
        os.environ.setdefault("JAX_PLATFORMS", "cpu")
    if args.quick:
        args.gait_horizon, args.gait_per_device, args.gait_total = 0.1, 8, 16
        args.agree_block, args.repeats = 4, 2
        args.tsp_speed_instance, args.islands_per_device, args.islands_total = "eil51", 2, 4
        args.tsp_chunk, args.islands, args.ants_per_island = 3, 4, 10
        args.seeds, args.group, args.tsp_seconds = 4, 4, 5.0
        args.tsp_instances, args.cec_problems, args.cec_evaluations = "eil51", "g13", 20_000
    args.tsp_instances = [s for s in args.tsp_instances.split(",") if s]
    args.cec_problems = [s for s in args.cec_problems.split(",") if s]

    import jax

    env = environment()
    kind = env["device_kind"].replace(" ", "_").lower()
    out = args.out or RESULTS / f"islands_scaling_{kind}_{env['devices']}dev.json"
    print(f"{env['devices']} x {env['device_kind']} ({env['platform']}), jax {jax.__version__}")
    parts = {"gait": part_gait, "agree": part_agree, "tsp": part_tsp, "quality": part_quality}
    record: dict[str, Any] = {"environment": env, "args": {k: v for k, v in vars(args).items()
                                                            if k != "out"}, "rows": []}
    for name in args.parts.split(","):
        record["rows"] += parts[name](args)
        out.parent.mkdir(parents=True, exist_ok=True)
        from eaco_jax.outputs import write_json

        write_json(out, record)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
