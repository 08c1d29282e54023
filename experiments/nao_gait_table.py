"""The constraint table of a stored NAO gait: per leg joint and per world, on one world stream.

Issue 30 asks, for every stored gait: each leg joint's winding temperature after ten minutes
of continuous walking and at steady state against the firmware limit, the peak current
against the current limit, slip per metre and drift, with the falls. This script walks a gait
record on native MuJoCo in the nominal world and in ``--worlds`` randomised worlds of
``--stream`` (default ``test``: nothing was chosen on them) of the record's seed, with the
record's steering and target noise (``eaco gait`` stores both), and writes (a turning gait,
``turn`` in the record, has no drift constraint; ``--seed`` takes another run seed's stream,
e.g. a selection stream no search used, to compare gaits):

* ``nominal``: every constraint's value in the nominal world;
* ``worlds``: per constraint the worst, 99th and 95th percentile and median world and the
  number of worlds past the limit; the falls with their Clopper-Pearson interval; the number
  of worlds meeting every constraint;
* ``legs_nominal`` / ``legs_worlds``: per leg joint (the hotter of left and right) the winding
  after ten minutes and at steady state (the projection of :mod:`eaco_jax.gait.motors` from
  the 20 s walk's losses), in the nominal world and in the hottest world that did not fall;
* ``walking_worlds_worst``: each constraint's worst value over the worlds that did not fall,
  and the shortest endurance (minutes until a winding reaches the firmware limit).

Reproduce (about 3 min for 400 worlds on 2 CPU cores):

    JAX_PLATFORMS=cpu python experiments/nao_gait_table.py \
        experiments/results/nao_steer_margin_gpu/best_gait.json --worlds 400
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import platform
import sys
import time
from pathlib import Path

import jax
import mujoco
import numpy as np

from eaco_jax.gait import constraints as gc
from eaco_jax.gait import quality as ql
from eaco_jax.gait.fitness import gait_fitness
from eaco_jax.gait.stats import fall_rate
from eaco_jax.gait.thermal_walk import LEG_ROLES
from eaco_jax.gait.worlds import stream_key
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.runs.gait import params_vector, read_params_file, steering_of, world_ranges


def per_world(p, x, worlds) -> dict[str, np.ndarray]:
    """Constraint values per world ``(R,)`` and per world and joint ``(R, nu)``."""
    r = 1 if worlds is None else worlds.size
    out = jax.jit(lambda x: p._rollout(x, worlds, True))(x)
    summary = p.summarize(out["trace"])
    res = gait_fitness(summary, p.direction_deg, p.turn)
    res.update(p._quality(out["acc"], res["distance_m"], worlds, r))
    walked = np.maximum(np.asarray(res["distance_m"], np.float64), gc.SLIP_MIN_DISTANCE)
    return {"t10": np.asarray(res["winding_10min_c"], np.float64),
            "steady": np.asarray(res["winding_steady_c"], np.float64),
            "current": np.asarray(res["peak_current_max_frac"], np.float64),
            "slip": np.asarray(res["foot_slip_m"], np.float64) / walked,
            "drift": np.asarray(res["drift_deg"], np.float64),
            "fell": np.asarray(res["fell"], bool),
            "endurance_min": np.asarray(res["min_endurance_min"], np.float64),
            "speed": np.asarray(res["speed_mps"], np.float64),
            "turn": np.asarray(res["turn_deg_s"], np.float64)}


def legs(v: dict[str, np.ndarray], names: tuple[str, ...]) -> dict[str, dict[str, float]]:
    """Per leg joint, over the worlds that did not fall (a fallen robot's projection to ten
    minutes of walking means nothing): the hottest world's windings and the spread."""
    out = {}
    walking = np.flatnonzero(~v["fell"])
    for role in LEG_ROLES:
        idx = [i for i, n in enumerate(names) if n.endswith(role)]
        t10 = v["t10"][walking][:, idx].max(axis=1)
        w = int(walking[int(t10.argmax())])
        out[role] = {"t10_c": float(t10.max()),
                     "steady_c": float(v["steady"][w, idx].max()),
                     "t10_p99_c": float(np.percentile(t10, 99)),
                     "t10_median_c": float(np.median(t10)),
                     "world": w}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("gait")
    ap.add_argument("--worlds", type=int, default=400)
    ap.add_argument("--stream", default="test", choices=("test", "selection", "optimisation"))
    ap.add_argument("--seed", type=int, default=None,
                    help="run seed whose stream the worlds come from (default: the record's); "
                         "a fresh seed's selection stream compares gaits on worlds none has seen")
    ap.add_argument("--out", type=Path, default=None,
                    help="JSON path (default: table_native_<stream><worlds>.json beside the gait)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    data = read_params_file(a.gait)
    seed = int(data.get("seed") or 0) if a.seed is None else int(a.seed)
    noise = (data.get("robust") or {}).get("target_noise")
    cfg = world_ranges(seed, noise, R=a.worlds)
    p = make_gait_problem(str(data.get("robot", "nao")), backend="native",
                          horizon=float(data.get("horizon") or 20.0),
                          direction_deg=float(data.get("direction") or 0.0),
                          slope_deg=float(data.get("slope") or 0.0), robust=cfg,
                          turn=data.get("turn"),
                          constrained=True, steering=steering_of(None, data))
    x = p.gait_row(params_vector(data, p, a.gait))
    lim = gc.limits(ql.mo.motor_model(p.spec), p.horizon)
    nom = per_world(p, x, None)
    v = per_world(p, x, p.worlds(stream_key(seed, a.stream, 0), a.worlds))
    hot = v["t10"].max(axis=1)
    over = {"endurance": hot >= lim["endurance"], "current": v["current"] > lim["current"],
            "slip": v["slip"] > lim["slip"], "drift": v["drift"] > lim["drift"],
            "falls": v["fell"]}
    vals = {"endurance": hot, "current": v["current"], "slip": v["slip"], "drift": v["drift"]}
    kept = gc.names(p.turn)  # a turning gait has no drift constraint: turning is its objective
    over = {k: a_ for k, a_ in over.items() if k in kept}
    vals = {k: a_ for k, a_ in vals.items() if k in kept}
    walking = ~v["fell"]
    walking_worst = {k: float(a_[walking].max()) for k, a_ in vals.items()} | {
        "endurance_min": float(v["endurance_min"][walking].min())}
    worlds = {k: {"max": float(a_.max()), "p99": float(np.percentile(a_, 99)),
                  "p95": float(np.percentile(a_, 95)), "median": float(np.median(a_)),
                  "over": int(over[k].sum()), "limit": lim[k]} for k, a_ in vals.items()}
    ok = ~np.any(np.stack(list(over.values())), axis=0)
    record = {
        "gait": a.gait, "seed": seed, "stream": a.stream, "batch": 0, "worlds": a.worlds,
        "slope": p.slope_deg, "direction": p.direction_deg, "turn": p.turn,
        "backend": "native", "steering": data.get("steering"),
        "robust": dataclasses.asdict(cfg),
        "nominal": {"t10_c": float(nom["t10"].max()), "steady_c": float(nom["steady"].max()),
                    "current": float(nom["current"][0]), "slip": float(nom["slip"][0]),
                    "drift": float(nom["drift"][0]), "fell": bool(nom["fell"][0]),
                    "speed": float(nom["speed"][0]),
                    "endurance_min": float(nom["endurance_min"][0])},
        "walking_worlds_worst": walking_worst,
        "legs_nominal": legs(nom, p.spec.joint_names),
        "legs_worlds": legs(v, p.spec.joint_names),
        "constraints": worlds,
        "falls": fall_rate(int(v["fell"].sum()), a.worlds),
        "all_constraints_met": int(ok.sum()),
        "speed_mean": float(v["speed"].mean()),
        "turn_deg_s_mean": float(v["turn"].mean()),
        "per_world": {k: a_.tolist() for k, a_ in vals.items()} | {
            "fell": v["fell"].tolist(), "speed": v["speed"].tolist()},
        "seconds": time.perf_counter() - t0,
        "command": "python " + " ".join(sys.argv),
        "date": datetime.date.today().isoformat(),
        "device": platform.processor() or platform.machine(), "mujoco": mujoco.__version__,
        "jax": jax.__version__,
    }
    out = a.out or Path(a.gait).parent / f"table_native_{a.stream}{a.worlds}.json"
    out.write_text(json.dumps(record, indent=1))
    print(f"nominal: {record['nominal']}")
    for k, row in worlds.items():
        print(f"{k:<10} max {row['max']:.4g} p99 {row['p99']:.4g} median {row['median']:.4g} "
              f"over {row['over']} (limit {row['limit']:.4g})")
    print(f"falls {record['falls']}; all constraints met in {record['all_constraints_met']} of "
          f"{a.worlds}; speed {record['speed_mean']:.3f} m/s")
    for role, row in record["legs_worlds"].items():
        print(f"{role:<12} nominal {record['legs_nominal'][role]['t10_c']:.1f} / "
              f"{record['legs_nominal'][role]['steady_c']:.1f} C; hottest world "
              f"{row['t10_c']:.1f} / {row['steady_c']:.1f} C")
    print(f"wrote {out} ({record['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
