"""Screen gaits near a stored one for falls under randomisation, then validate the winner.

Issue 12 asks for a stored flat-ground gait with 0 falls in 100 randomised 20 s trials on
both backends and with ``--accurate``, at >= 0.47 m/s. The stored gait (0.63 m/s) falls in
4-5 of 100. A slower gait with more margin is the trade the issue allows; this script finds
one by measurement, in three stages with disjoint world streams:

1. **screen**: ``--candidates`` gaits (the stored one; its step length and period scaled;
   Gaussian perturbations of each) in ``--screen-worlds`` randomised worlds each, one batched
   rollout (world stream 2, seed 0);
2. **confirm**: the ``--finalists`` fastest gaits without a fall in ``--confirm-worlds`` fresh
   worlds (stream 2, seed 1);
3. **validate**: the fastest finalist without a fall (fewest falls otherwise) and the stored
   gait with :func:`eaco_jax.gait.validate.evaluate_trials` (stream 1, seed 0: what
   ``eaco gait-eval --trials 100`` draws) on MJX, native and native ``--accurate``.

``--confirm-jax K`` re-runs the K best finalists in fresh worlds on MJX's JAX implementation
(a second numerical path; the winner has the fewest falls over both). ``--base FILE`` screens
around another gait (a slope or sideways gait: its slope and direction are kept).
The default ranges of :class:`~eaco_jax.gait.worlds.RobustConfig` throughout. GPU::

    python experiments/gait_screen.py --out $OUT/gait_screen.json --params-out $OUT/gait.json

Writes JSON with the device, versions and every stage's numbers, and the winner as a gait
file (``eaco gait-eval`` reads it).
"""

from __future__ import annotations

import argparse
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

from eaco_jax.gait.validate import evaluate_trials
from eaco_jax.gait.worlds import RobustConfig, world_key
from eaco_jax.problems.gait import make_gait_problem

HERE = Path(__file__).resolve().parent
STORED = HERE / "results" / "nao_best_gait.json"
SCREEN_STREAM = 2  # optimisation draws from stream 0, validation trials from stream 1
FIXED = ("direction", "turn_rate")  # straight walking: not perturbed


def log(*a: Any) -> None:
    print(*a, flush=True)


def candidates(problem, base: np.ndarray, n: int, sigma: float, seed: int,
               step_scales=(1.0, 0.9, 0.8, 0.7, 0.6),
               period_scales=(1.0, 1.1, 1.2, 1.35)) -> np.ndarray:
    """The stored gait, its scaled variants (step length x period) and perturbations."""
    names = list(problem.param_names)
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    variants = []
    for a in step_scales:
        for b in period_scales:
            v = base.copy()
            v[names.index("step_length")] *= a
            v[names.index("period")] *= b
            variants.append(v)
    variants = np.clip(np.array(variants), lo, hi)
    rng = np.random.default_rng(seed)
    free = np.array([nm not in FIXED for nm in names])
    out = list(variants)
    while len(out) < n:
        v = variants[len(out) % len(variants)]
        step = rng.normal(0.0, sigma, v.shape) * (hi - lo) * free
        out.append(np.clip(v + step, lo, hi))
    return np.asarray(out[:n], np.float32)


def rollout_stats(problem, x: np.ndarray, key, r: int, chunk: int) -> dict[str, np.ndarray]:
    """Falls and mean speed of every gait over ``r`` randomised worlds (one call per chunk
    of gaits, the same worlds for all)."""
    worlds = problem.worlds(key, r)
    run = jax.jit(lambda xs, w: problem.rollout(xs, w, quality=False))
    speed, dist, fell = [], [], []
    for i in range(0, len(x), chunk):
        res = run(jnp.asarray(x[i:i + chunk]), worlds)
        fell.append(np.asarray(res["fell"]))
        speed.append(np.asarray(res["speed_mps"]).mean(axis=1))
        dist.append(np.asarray(res["distance_m"]).min(axis=1))
    fell = np.concatenate(fell)  # (gaits, worlds)
    return {"falls": fell.sum(axis=1), "speed": np.concatenate(speed),
            "min_distance": np.concatenate(dist), "fell": fell, "worlds": worlds}


def fall_worlds(stats: dict, row: int) -> list[dict]:
    """The randomised conditions of the worlds in which gait ``row`` fell (for diagnosis)."""
    w = stats["worlds"]
    out = []
    for j in np.flatnonzero(stats["fell"][row]):
        f = np.asarray(w.push_force[j])
        out.append({"world": int(j), "friction": float(w.friction[j]),
                    "latency": int(w.latency[j]), "push_start_step": int(w.push_start[j]),
                    "push_force_n": float(np.hypot(f[0], f[1])),
                    "push_angle_deg": float(np.degrees(np.arctan2(f[1], f[0])))})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", type=Path, default=STORED,
                    help="the gait to screen around (its slope and direction are kept)")
    ap.add_argument("--backend", default="mjx")
    ap.add_argument("--impl", default="auto")
    ap.add_argument("--horizon", type=float, default=20.0)
    ap.add_argument("--candidates", type=int, default=1024)
    ap.add_argument("--sigma", type=float, default=0.03, help="perturbation, fraction of range")
    ap.add_argument("--screen-worlds", type=int, default=64)
    ap.add_argument("--finalists", type=int, default=32)
    ap.add_argument("--confirm-worlds", type=int, default=512)
    ap.add_argument("--min-speed", type=float, default=0.5)
    ap.add_argument("--step-scales", default="1.0,0.9,0.8,0.7,0.6",
                    help="step-length factors of the stored gait's variants")
    ap.add_argument("--period-scales", default="1.0,1.1,1.2,1.35",
                    help="period factors of the stored gait's variants")
    ap.add_argument("--confirm-jax", type=int, default=0,
                    help="re-confirm the best K finalists on MJX's JAX implementation too "
                         "(a second numerical path; the winner has the fewest falls over both)")
    ap.add_argument("--confirm-jax-worlds", type=int, default=1024)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--chunk", type=int, default=1024, help="gaits per batched call")
    ap.add_argument("--validate-backends", default="mjx,native,accurate",
                    help="mjx (the problem's impl), mjx-jax, native, accurate (native)")
    ap.add_argument("--no-validate-stored", dest="validate_stored", action="store_false")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--params-out", default=None)
    args = ap.parse_args()
    device = jax.devices()[0].device_kind if jax.default_backend() != "cpu" else "cpu"
    stored = json.loads(args.base.read_text())
    base = np.asarray(stored["vector"], np.float32)
    where = {"slope_deg": float(stored.get("slope_deg", 0.0)),
             "direction_deg": float(stored.get("direction_deg", 0.0))}
    cfg = RobustConfig()
    problem = make_gait_problem("nao", backend=args.backend, horizon=args.horizon,
                                robust=cfg, impl=args.impl, **where)
    record: dict[str, Any] = {
        "device": device, "jax": jax.__version__, "mujoco": mujoco.__version__,
        "python": platform.python_version(), "argv": sys.argv[1:], "backend": problem.backend,
        "impl": getattr(problem, "impl", None), "base": str(args.base), **where,
        "robust": {k: getattr(cfg, k) for k in (
            "friction", "mass", "motor", "target_noise", "latency", "init_noise", "push",
            "push_duration")},
    }
    out = Path(args.out or HERE / "results" / "gpu" / "gait_screen.json")
    out.parent.mkdir(parents=True, exist_ok=True)

    def save() -> None:
        out.write_text(json.dumps(record, indent=1, default=float) + "\n")

    scales = [tuple(float(v) for v in a.split(",")) for a in (args.step_scales,
                                                               args.period_scales)]
    x = candidates(problem, base, args.candidates, args.sigma, args.seed, *scales)
    t0 = time.perf_counter()
    a = rollout_stats(problem, x, world_key(args.seed, 0, SCREEN_STREAM), args.screen_worlds,
                      args.chunk)
    record["screen"] = {
        "candidates": len(x), "worlds": args.screen_worlds, "seconds": time.perf_counter() - t0,
        "no_fall": int(np.sum(a["falls"] == 0)),
        "no_fall_and_fast": int(np.sum((a["falls"] == 0) & (a["speed"] >= args.min_speed))),
        "stored": {"falls": int(a["falls"][0]), "speed_mps": float(a["speed"][0])},
    }
    log("screen", record["screen"])
    save()
    order = np.lexsort((-a["speed"], a["falls"] > 0, a["speed"] < args.min_speed))
    fin = order[:args.finalists]
    t0 = time.perf_counter()
    b = rollout_stats(problem, x[fin], world_key(args.seed + 1, 0, SCREEN_STREAM),
                      args.confirm_worlds, args.chunk)
    record["confirm"] = {
        "worlds": args.confirm_worlds, "seconds": time.perf_counter() - t0,
        "rows": [{"candidate": int(i), "screen_falls": int(a["falls"][i]),
                  "screen_speed_mps": float(a["speed"][i]), "falls": int(f),
                  "speed_mps": float(s), "vector": x[i].tolist()}
                 for i, f, s in zip(fin, b["falls"], b["speed"], strict=True)],
    }
    log("confirm", [(r["falls"], round(r["speed_mps"], 3)) for r in record["confirm"]["rows"]])
    save()
    rank = np.lexsort((-b["speed"], b["falls"], b["speed"] < args.min_speed))
    total = b["falls"].astype(np.int64)
    if args.confirm_jax and not (problem.backend == "mjx" and problem.impl == "jax"):
        top = rank[:args.confirm_jax]
        pj = make_gait_problem("nao", backend="mjx", horizon=args.horizon, robust=cfg,
                               impl="jax", **where)
        t0 = time.perf_counter()
        c = rollout_stats(pj, x[fin[top]], world_key(args.seed + 2, 0, SCREEN_STREAM),
                          args.confirm_jax_worlds, args.chunk)
        record["confirm_jax"] = {
            "worlds": args.confirm_jax_worlds, "seconds": time.perf_counter() - t0,
            "rows": [{"candidate": int(fin[i]), "falls": int(f), "speed_mps": float(s),
                      "fall_worlds": fall_worlds(c, j)}
                     for j, (i, f, s) in enumerate(zip(top, c["falls"], c["speed"],
                                                       strict=True))]}
        log("confirm jax", [(r["falls"], round(r["speed_mps"], 3))
                            for r in record["confirm_jax"]["rows"]])
        # only the re-confirmed finalists compete: falls over both numerical paths
        total = np.full(len(fin), np.iinfo(np.int64).max // 2)
        total[top] = b["falls"][top] + c["falls"]
        save()
    rank = np.lexsort((-b["speed"], total, b["speed"] < args.min_speed))
    win = fin[rank[0]]
    record["winner"] = {"candidate": int(win), "vector": x[win].tolist(),
                        "params": problem.params_dict(x[win]),
                        "confirm_falls": int(b["falls"][rank[0]]),
                        "confirm_fall_worlds": fall_worlds(b, int(rank[0])),
                        "confirm_speed_mps": float(b["speed"][rank[0]])}
    save()

    def write_gait() -> None:  # the winner as a gait file, its trials as they come
        if not args.params_out:
            return
        gait = {"robot": "nao", **where,
                "params": problem.params_dict(x[win]), "vector": x[win].tolist(),
                "horizon": args.horizon,
                "source": f"experiments/gait_screen.py: screened near {args.base.name} "
                          f"({args.candidates} gaits x {args.screen_worlds} worlds, "
                          f"{args.finalists} x {args.confirm_worlds}) on {device}",
                "trials": {k: v for k, v in record["validate"].items()
                           if k.startswith("winner")}}
        Path(args.params_out).write_text(json.dumps(gait, indent=1, default=float) + "\n")

    record["validate"] = {}
    write_gait()
    for which in args.validate_backends.split(","):
        backend = {"accurate": "native", "mjx-jax": "mjx"}.get(which, which)
        impl = "jax" if which == "mjx-jax" else (args.impl if backend == "mjx" else "auto")
        p = make_gait_problem("nao", backend=backend, horizon=args.horizon, robust=cfg,
                              impl=impl, **where)
        gaits = [("winner", x[win])] + ([("stored", base)] if args.validate_stored else [])
        for label, vec in gaits:
            t0 = time.perf_counter()
            tr = evaluate_trials(p, vec, n=args.trials, seed=0, accurate=which == "accurate")
            tr["seconds"] = time.perf_counter() - t0
            record["validate"][f"{label}_{which}"] = tr
            log(f"validate {label:6s} {which:8s}: falls {tr['falls']}/{tr['n']}, "
                f"{tr['speed_mps_mean']:.3f} +- {tr['speed_mps_ci95']:.3f} m/s, "
                f"CoT {tr['cost_of_transport_mean']:.2f}")
            save()
            write_gait()
    log(f"wrote {out}")


if __name__ == "__main__":
    main()
