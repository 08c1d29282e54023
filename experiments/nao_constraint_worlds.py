"""What in the randomised worlds drives the constrained NAO gait's worst-world slip and drift?

Issue 30: the constrained gait search finds no feasible gait; its closest gait
(``experiments/results/nao_constrained_gpu_deb16/best_gait.json``, chosen on MJX) violates
endurance, slip per metre and drift in its worst of 64 selection-stream worlds. This script
re-evaluates that gait on native MuJoCo in the same 64 worlds (the record's seed, stream
``selection``, batch 0, drawn by ``GaitProblem.worlds`` with the search's ``RobustConfig``
ranges, as ``eaco gait`` drew them for the record's ``constraints`` block) and records, per
world, the world's factors and the constraint values: slip per metre (the constraint's
``foot_slip_m / max(distance, 0.1 m)``), drift (deg, the constraint's; also signed, + = left),
the hottest winding after ten minutes ``t10_c`` (C), fell and speed (m/s).

Then it repeats the evaluation in the same worlds with one factor set to its nominal value
(counterfactuals ``no_push``: push force zero, ``nominal_friction``: the model's sliding
friction 1.0 on floor and soles, ``zero_latency``, ``nominal_motors``: stall and speed scales 1,
``no_target_noise``, ``nominal_mass``, ``no_init_noise``), with every factor nominal but one
(``only_*``), with another draw of the target noise at the same std (``resampled_noise``) and
in the nominal world alone (no ``Worlds``: the nominal models, no push). Each counterfactual
also gets the Spearman correlation of its per-world values with the baseline's (same world,
other factor): a low one means a world's value is not a property of its factors.
Each scenario is the sampled ``Worlds`` pytree with fields replaced (``Worlds.replace``); the
library is unchanged. Spearman correlations relate each world factor to drift and slip in the
baseline. Per scenario: max, 95th percentile, mean and the number of worlds over each limit
(slip 0.05 m/m, drift 10 deg, T_10min 75 C).

Reproduce (about 6 min on 2 CPU cores):

    JAX_PLATFORMS=cpu python experiments/nao_constraint_worlds.py
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from scipy import stats

from eaco_jax.gait import constraints as gc
from eaco_jax.gait import quality as ql
from eaco_jax.gait.fitness import gait_fitness
from eaco_jax.gait.worlds import RobustConfig, Worlds, joint_play_offsets, stream_key
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.runs.gait import params_vector, read_params_file

REPO = Path(__file__).resolve().parent.parent
GAIT = "experiments/results/nao_constrained_gpu_deb16/best_gait.json"
OUT = "experiments/results/nao_constraint_worlds.json"
NOMINAL_FRICTION = 1.0
"""The NAO model's sliding friction of the floor and every sole geom (the worlds' range,
0.5-1.0, lies at or below it)."""
FACTORS = ("push", "friction", "latency", "motors", "target_noise", "mass", "init_noise")
COUNTERFACTUAL = {"push": "no_push", "friction": "nominal_friction",
                  "latency": "zero_latency", "motors": "nominal_motors",
                  "target_noise": "no_target_noise", "mass": "nominal_mass",
                  "init_noise": "no_init_noise"}
LEFT_LEG = ("LHipYawPitch", "LHipRoll", "LHipPitch", "LKneePitch", "LAnklePitch", "LAnkleRoll")
RIGHT_LEG = tuple("R" + n[1:] for n in LEFT_LEG)


def nominal(worlds: Worlds, factor: str) -> Worlds:
    """``worlds`` with one factor at its nominal value (same keys, every other field kept)."""
    if factor == "push":
        return worlds.replace(push_force=jnp.zeros_like(worlds.push_force))
    if factor == "friction":
        return worlds.replace(friction=jnp.full_like(worlds.friction, NOMINAL_FRICTION))
    if factor == "latency":
        return worlds.replace(latency=jnp.zeros_like(worlds.latency))
    if factor == "motors":
        return worlds.replace(stall_scale=jnp.ones_like(worlds.stall_scale),
                              speed_scale=jnp.ones_like(worlds.speed_scale))
    if factor == "target_noise":
        return worlds.replace(noise_std=jnp.zeros_like(worlds.noise_std))
    if factor == "mass":
        return worlds.replace(mass_scale=jnp.ones_like(worlds.mass_scale))
    if factor == "init_noise":
        return worlds.replace(init_dq=jnp.zeros_like(worlds.init_dq))
    raise ValueError(f"unknown factor {factor!r}")


def only(worlds: Worlds, keep: str) -> Worlds:
    """``worlds`` with every factor nominal but ``keep``."""
    for f in FACTORS:
        if f != keep:
            worlds = nominal(worlds, f)
    return worlds


def per_world(p, x: jax.Array, worlds: Worlds | None) -> dict[str, np.ndarray]:
    """One gait ``x`` ``(1, dim)`` in each world: the constraint values per world plus the signed
    drift and the heading turned. The steps of ``GaitProblem.rollout(..., quality=True)``
    (one native rollout), keeping the torso trace for the signed drift."""
    r = 1 if worlds is None else worlds.size
    out = p._rollout(x, worlds, True)
    summary = p.summarize(out["trace"])
    res = gait_fitness(summary, p.direction_deg, p.turn)
    res.update(p._quality(out["acc"], res["distance_m"], worlds, r))
    disp = np.asarray(summary.end_xy - summary.start_xy, np.float64)
    a = math.radians(p.direction_deg)
    along = disp[:, 0] * math.cos(a) + disp[:, 1] * math.sin(a)
    across = disp[:, 1] * math.cos(a) - disp[:, 0] * math.sin(a)
    t10 = np.asarray(res["winding_10min_c"], np.float64)  # (R, nu)
    walked = np.maximum(np.asarray(res["distance_m"], np.float64), gc.SLIP_MIN_DISTANCE)
    return {
        "slip_per_m": np.asarray(res["foot_slip_m"], np.float64) / walked,
        "drift_deg": np.asarray(res["drift_deg"], np.float64),
        "t10_c": t10.max(axis=-1),
        "fell": np.asarray(res["fell"], bool),
        "speed": np.asarray(res["speed_mps"], np.float64),
        "signed_drift_deg": np.degrees(np.arctan2(across, along)),
        "turned_deg": np.asarray(summary.turned_deg, np.float64),
        "distance_m": np.asarray(res["distance_m"], np.float64),
        "foot_slip_m": np.asarray(res["foot_slip_m"], np.float64),
        "hottest_joint": np.asarray([p.spec.joint_names[i] for i in t10.argmax(axis=-1)]),
        "peak_current_frac": np.asarray(res["peak_current_max_frac"], np.float64),
    }


def summary(v: dict[str, np.ndarray], lim: dict[str, float]) -> dict[str, Any]:
    """Max, 95th percentile, mean and worlds over each limit (the worst world's index too)."""
    out: dict[str, Any] = {}
    for key, limit in (("slip_per_m", lim["slip"]), ("drift_deg", lim["drift"]),
                       ("t10_c", lim["endurance"]), ("speed", None)):
        a = v[key]
        row = {"max": float(a.max()), "p95": float(np.percentile(a, 95)),
               "mean": float(a.mean()), "min": float(a.min()), "argmax": int(a.argmax())}
        if limit is not None:
            row["limit"] = float(limit)
            row["over"] = int(np.sum(a > limit))
        out[key] = row
    sd = v["signed_drift_deg"]
    out["signed_drift_deg"] = {"mean": float(sd.mean()),
                               "sd": float(sd.std(ddof=1)) if sd.size > 1 else 0.0,
                               "min": float(sd.min()), "max": float(sd.max())}
    out["falls"] = int(np.sum(v["fell"]))
    out["feasible_worlds"] = int(np.sum((v["slip_per_m"] <= lim["slip"])
                                        & (v["drift_deg"] <= lim["drift"])
                                        & (v["t10_c"] <= lim["endurance"]) & ~v["fell"]))
    return out


def factor_table(p, worlds: Worlds) -> dict[str, np.ndarray]:
    """Each world's factors, one number per world (per-joint scales also kept whole)."""
    names = p.spec.joint_names
    legs_l = [names.index(n) for n in LEFT_LEG]
    legs_r = [names.index(n) for n in RIGHT_LEG]
    legs = legs_l + legs_r
    force = np.asarray(worlds.push_force, np.float64)
    dt = p.spec.control_dt
    steps = np.asarray(worlds.push_stop - worlds.push_start, np.float64)
    a = math.radians(p.direction_deg)
    stall = np.asarray(worlds.stall_scale, np.float64)
    speed = np.asarray(worlds.speed_scale, np.float64)
    mass = np.asarray(worlds.mass_scale, np.float64)
    return {
        "friction": np.asarray(worlds.friction, np.float64),
        "latency_steps": np.asarray(worlds.latency, np.float64),
        "push_impulse_ns": np.linalg.norm(force[:, :2], axis=-1) * steps * dt,
        "push_force_n": np.linalg.norm(force[:, :2], axis=-1),
        "push_forward_n": force[:, 0] * math.cos(a) + force[:, 1] * math.sin(a),
        "push_left_n": force[:, 1] * math.cos(a) - force[:, 0] * math.sin(a),
        "push_abs_lateral_n": np.abs(force[:, 1] * math.cos(a) - force[:, 0] * math.sin(a)),
        "push_angle_deg": np.degrees(np.arctan2(force[:, 1], force[:, 0])),
        "push_start_s": np.asarray(worlds.push_start, np.float64) * dt,
        "stall_mean": stall.mean(axis=-1),
        "speed_mean": speed.mean(axis=-1),
        "stall_legs_mean": stall[:, legs].mean(axis=-1),
        "speed_legs_mean": speed[:, legs].mean(axis=-1),
        "stall_legs_left_minus_right": stall[:, legs_l].mean(-1) - stall[:, legs_r].mean(-1),
        "speed_legs_left_minus_right": speed[:, legs_l].mean(-1) - speed[:, legs_r].mean(-1),
        "mass_mean": mass[:, 1:].mean(axis=-1),
        "mass_torso": mass[:, 1],
        "init_dq_rms": np.sqrt(np.mean(np.asarray(worlds.init_dq, np.float64) ** 2, axis=-1)),
    }


SIGNED_FACTORS = ("push_left_n", "stall_legs_left_minus_right", "speed_legs_left_minus_right")


def correlations(factors: dict[str, np.ndarray], v: dict[str, np.ndarray]) -> dict[str, Any]:
    """Spearman's rho (and p) of each factor with drift, slip per metre and T_10min; signed
    factors also with the signed drift."""
    out: dict[str, Any] = {}
    for name, f in factors.items():
        row = {}
        targets = ["drift_deg", "slip_per_m", "t10_c"]
        if name in SIGNED_FACTORS:
            targets.append("signed_drift_deg")
        for t in targets:
            if np.ptp(f) == 0:
                row[t] = None
                continue
            res = stats.spearmanr(f, v[t])
            row[t] = {"rho": float(res.statistic), "p": float(res.pvalue)}
        out[name] = row
    return out


def jsonable(v: dict[str, Any]) -> dict[str, Any]:
    return {k: (a.tolist() if isinstance(a, np.ndarray) else a) for k, a in v.items()}


def git_hash() -> str:
    try:
        return subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def plot(path: Path, scenarios: dict[str, dict[str, Any]], lim: dict[str, float]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(scenarios)
    fig, axes = plt.subplots(1, 3, figsize=(15, 0.35 * len(names) + 1.5), sharey=True)
    for ax, key, limit, label in ((axes[0], "drift_deg", lim["drift"], "drift [deg]"),
                                  (axes[1], "slip_per_m", lim["slip"], "slip per metre [m/m]"),
                                  (axes[2], "t10_c", lim["endurance"], "T after 10 min [C]")):
        for i, n in enumerate(names):
            a = np.asarray(scenarios[n]["per_world"][key])
            ax.scatter(a, np.full_like(a, i) + np.random.default_rng(i).uniform(-.2, .2, a.size),
                       s=6, alpha=0.6)
        ax.axvline(limit, color="red", lw=1)
        ax.set_xlabel(label)
    axes[0].set_yticks(range(len(names)), names)
    axes[0].invert_yaxis()
    fig.suptitle("deb16 gait, native MuJoCo, 64 selection-stream worlds per scenario")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gait", default=GAIT)
    ap.add_argument("--worlds", type=int, default=None,
                    help="selection-stream worlds (default: the record's selection worlds)")
    ap.add_argument("--out", type=Path, default=Path(OUT))
    ap.add_argument("--no-only", action="store_true", help="skip the only_* scenarios")
    ap.add_argument("--no-plot", action="store_true")
    ap.add_argument("--noise-scan", type=float, nargs="*", default=[],
                    help="also the sampled worlds with the target noise at each of these stds "
                         "(rad; same noise key), scenarios noise_std_<value>")
    ap.add_argument("--joint-play", type=float, nargs="*", default=[],
                    help="also the sampled worlds with joint-play offsets of each of these "
                         "half-widths (rad; RobustConfig.joint_play's draw) and target noise "
                         "--play-noise, scenarios play_<value>")
    ap.add_argument("--play-noise", type=float, default=0.0005,
                    help="target noise std (rad) of the --joint-play scenarios")
    a = ap.parse_args()
    t_start = time.perf_counter()
    data = read_params_file(a.gait)
    seed = int(data.get("seed") or 0)
    horizon = float(data.get("horizon") or 20.0)
    sel = data.get("selection") or {}
    n = int(a.worlds or sel.get("worlds") or data.get("constraints", {}).get("worlds") or 64)
    robust = data.get("robust") or {}
    cfg = RobustConfig(R=n, aggregate=robust.get("aggregate", "cvar"), seed=seed)
    p = make_gait_problem(str(data.get("robot", "nao")), backend="native", horizon=horizon,
                          direction_deg=float(data.get("direction") or 0.0),
                          slope_deg=float(data.get("slope") or 0.0), robust=cfg,
                          constrained=True)
    x = p.gait_row(params_vector(data, p, a.gait))
    wkey = stream_key(seed, "selection", 0)
    worlds = p.worlds(wkey, n)
    lim = gc.limits(ql.mo.motor_model(p.spec), horizon)

    plan: list[tuple[str, str, Worlds | None]] = [("baseline", "the sampled worlds", worlds)]
    for f in FACTORS:
        plan.append((COUNTERFACTUAL[f], f"{f} nominal, the rest as sampled", nominal(worlds, f)))
    if not a.no_only:
        for f in FACTORS:
            plan.append((f"only_{f}", f"{f} as sampled, the rest nominal", only(worlds, f)))
    plan.append(("resampled_noise", "the sampled worlds with another target-noise key "
                 "(same std): how much a world's values depend on the noise draw",
                 worlds.replace(noise_key=jax.random.fold_in(worlds.noise_key, 1))))
    for std in a.noise_scan:
        plan.append((f"noise_std_{std:g}", f"the sampled worlds with target noise std {std:g} rad "
                     "(same key), the rest as sampled",
                     worlds.replace(noise_std=jnp.full_like(worlds.noise_std, std))))
    for play in a.joint_play:
        plan.append((f"play_{play:g}", f"the sampled worlds with joint-play offsets U(-{play:g}, "
                     f"{play:g}) rad per joint and target noise std {a.play_noise:g} rad",
                     worlds.replace(noise_std=jnp.full_like(worlds.noise_std, a.play_noise),
                                    target_offset=joint_play_offsets(wkey, play, p.spec, n))))
    plan.append(("nominal", "the nominal world alone (no Worlds)", None))

    scenarios: dict[str, dict[str, Any]] = {}
    head = (f"{'scenario':<20} {'slip max':>8} {'p95':>6} {'>0.05':>5} {'drift max':>9} "
            f"{'p95':>6} {'>10':>4} {'sd+-':>5} {'T10 max':>7} {'>75':>4} {'speed':>6} {'s':>5}")
    print(head, flush=True)
    for name, what, w in plan:
        t0 = time.perf_counter()
        v = per_world(p, x, w)
        secs = time.perf_counter() - t0
        s = summary(v, lim)
        if w is not None and name != "baseline":
            s["spearman_with_baseline"] = {
                k: float(stats.spearmanr(v[k], scenarios["baseline"]["per_world"][k]).statistic)
                for k in ("drift_deg", "slip_per_m", "t10_c")}
        scenarios[name] = {"what": what, "seconds": secs, "summary": s, "per_world": jsonable(v)}
        print(f"{name:<20} {s['slip_per_m']['max']:8.4f} {s['slip_per_m']['p95']:6.4f} "
              f"{s['slip_per_m']['over']:5d} {s['drift_deg']['max']:9.2f} "
              f"{s['drift_deg']['p95']:6.2f} {s['drift_deg']['over']:4d} "
              f"{s['signed_drift_deg']['sd']:5.2f} "
              f"{s['t10_c']['max']:7.2f} {s['t10_c']['over']:4d} "
              f"{s['speed']['mean']:6.3f} {secs:5.1f}", flush=True)

    factors = factor_table(p, worlds)
    base = {k: np.asarray(val) for k, val in scenarios["baseline"]["per_world"].items()
            if k != "hottest_joint"}
    corr = correlations(factors, base)
    print("\nSpearman rho with the baseline's drift / slip (|rho| >= 0.25 or p < 0.05):")
    for fname, row in corr.items():
        d, sl = row["drift_deg"], row["slip_per_m"]
        if d is None:
            continue
        if max(abs(d["rho"]), abs(sl["rho"])) >= 0.25 or min(d["p"], sl["p"]) < 0.05:
            extra = ""
            if "signed_drift_deg" in row:
                sd = row["signed_drift_deg"]
                extra = f"  signed drift {sd['rho']:+.2f} (p {sd['p']:.3f})"
            print(f"  {fname:<30} drift {d['rho']:+.2f} (p {d['p']:.3f})  "
                  f"slip {sl['rho']:+.2f} (p {sl['p']:.3f}){extra}")

    shares = None
    if not a.no_only:  # each factor alone: its spread of the signed drift over the worlds
        var = {f: float(np.var(scenarios[f"only_{f}"]["per_world"]["signed_drift_deg"], ddof=1))
               for f in FACTORS}
        total = float(np.var(base["signed_drift_deg"], ddof=1))
        shares = {"signed_drift_var_alone": var, "sum_alone": sum(var.values()),
                  "baseline_var": total,
                  "share_of_sum": {f: v / max(sum(var.values()), 1e-12) for f, v in var.items()}}
        print("\nsigned drift variance (deg^2), each factor alone: "
              + ", ".join(f"{f} {v:.2f}" for f, v in var.items())
              + f"; sum {sum(var.values()):.2f}, all together {total:.2f}")

    record = {
        "question": "issue 30: which world factor drives the constrained NAO gait's worst-world "
                    "slip per metre and drift (selection-stream worlds, native MuJoCo)",
        "command": "JAX_PLATFORMS=cpu python " + " ".join(
            ["experiments/nao_constraint_worlds.py"] + sys.argv[1:]),
        "date": datetime.datetime.now(datetime.UTC).date().isoformat(),
        "device": f"cpu ({os.cpu_count()} cores, {platform.node()}), JAX on CPU",
        "versions": {"jax": jax.__version__, "mujoco": mujoco.__version__,
                     "eaco_jax": git_hash()},
        "seconds": None,
        "gait_file": a.gait,
        "gait_vector": np.asarray(x)[0].tolist(),
        "backend": "native",
        "horizon": horizon,
        "seed": seed,
        "stream": "selection",
        "batch": 0,
        "worlds": n,
        "robust_config": {k: (list(val) if isinstance(val, tuple) else val)
                          for k, val in dataclasses.asdict(cfg).items()},
        "worlds_drawn_by": "GaitProblem.worlds(stream_key(seed, 'selection', 0), n) with "
                           "RobustConfig(R=n, aggregate, seed) defaults, as "
                           "eaco_jax.runs.gait.constraints_record does",
        "limits": {"slip_per_m": lim["slip"], "drift_deg": lim["drift"],
                   "t10_c": lim["endurance"]},
        "nominal_friction": NOMINAL_FRICTION,
        "record_worst": {"backend": data.get("backend"),
                         **{k: data["constraints"]["constraints"][k]["value"]
                            for k in ("endurance", "slip", "drift")}}
        if "constraints" in data else None,
        "factors_per_world": jsonable(factors),
        "stall_scale_per_world": np.asarray(worlds.stall_scale).tolist(),
        "speed_scale_per_world": np.asarray(worlds.speed_scale).tolist(),
        "mass_scale_per_world": np.asarray(worlds.mass_scale).tolist(),
        "push_force_per_world": np.asarray(worlds.push_force).tolist(),
        "noise_std": float(worlds.noise_std),
        "joint_names": list(p.spec.joint_names),
        "spearman_baseline": corr,
        "signed_drift_variance": shares,
        "scenarios": scenarios,
    }
    record["seconds"] = time.perf_counter() - t_start
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(record, indent=1) + "\n")
    if not a.no_plot:
        plot(a.out.with_suffix(".png"), scenarios, lim)
    print(f"\nwrote {a.out} ({record['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
