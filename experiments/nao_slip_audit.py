"""What does the foot-slip figure measure? An audit of the sole spheres, control step by step.

Each gait (the stored one, ``experiments/results/nao_best_gait.json``, and the feasibility scan's
fastest ten-minute one, ``experiments/results/nao_endurance_seed_gait.json``) walks ``--horizon``
seconds in the nominal world (native MuJoCo, the spec's motor model); the configuration after
every control step is replayed through forward kinematics to get the four sole-sphere centres
of each foot. For each foot and pair of consecutive control steps with the foot in contact at
both (its lowest sphere within :data:`eaco_jax.gait.quality.CONTACT_TOL` of the floor, the
figure's rule) it records how many spheres are within the tolerance at both steps (0-4), how
far the foot's centre moves horizontally (the old figure, ``centre``) and how far the spheres
down at both steps move (their least: ``min``, their mean: ``mean``). The summary splits each
sum by the number of spheres down at both steps.

    python experiments/nao_slip_audit.py
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import mujoco
import numpy as np
from common import write_results

from eaco_jax.gait import quality as ql
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.rollout_native import floor_normal, native_model
from eaco_jax.problems.gait import make_gait_problem

GAITS = {"stored": "experiments/results/nao_best_gait.json",
         "fastest_ten_minute": "experiments/results/nao_endurance_seed_gait.json"}


def gait_vector(path: str) -> np.ndarray:
    """The parameter vector of a stored gait file (``vector``, else ``params`` by name)."""
    raw = json.loads(Path(path).read_text())
    if "vector" in raw:
        return np.asarray(raw["vector"], np.float32)
    return np.asarray([raw["params"][n] for n in we.PARAM_NAMES], np.float32)


def soles_of(p, qpos: np.ndarray) -> np.ndarray:
    """Sole-sphere centres ``(T, 8, 3)`` of configurations ``qpos`` ``(T, nq)``."""
    model = native_model(p.spec, float(p.slope_deg), p.accuracy)
    data = mujoco.MjData(model)
    ids = [model.geom(g).id for g in p.spec.foot_geoms]
    out = np.empty((len(qpos), len(ids), 3))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[t] = data.geom_xpos[ids]
    return out


def audit(soles: np.ndarray, radius: float, normal: np.ndarray) -> dict:
    """Per foot step (consecutive control steps, foot in contact at both): spheres down at both,
    centre displacement, least and mean displacement of the spheres down at both; summed."""
    h = (soles @ normal).reshape(len(soles), 2, ql.SOLES_PER_FOOT)
    down = h < radius + ql.CONTACT_TOL  # (T, 2, 4)
    foot = np.any(down, axis=-1)
    xy = soles[..., :2].reshape(len(soles), 2, ql.SOLES_PER_FOOT, 2)
    move = np.linalg.norm(xy[1:] - xy[:-1], axis=-1)  # (T-1, 2, 4) per sphere
    centre = np.linalg.norm(xy[1:].mean(-2) - xy[:-1].mean(-2), axis=-1)  # (T-1, 2)
    both = down[1:] & down[:-1]
    n = both.sum(-1)
    stance = foot[1:] & foot[:-1]
    mn = np.where(n > 0, np.min(np.where(both, move, np.inf), axis=-1), 0.0)
    mean = np.where(n > 0, np.sum(np.where(both, move, 0.0), -1) / np.maximum(n, 1), 0.0)
    rows = {}
    for k in range(5):
        sel = stance & (n == k)
        rows[str(k)] = {"foot_steps": int(sel.sum()), "centre_m": float(centre[sel].sum()),
                        "min_m": float(mn[sel].sum()), "mean_m": float(mean[sel].sum()),
                        "max_centre_step_mm": float(1e3 * centre[sel].max()) if sel.any()
                        else 0.0}
    return {"by_spheres_down_at_both": rows,
            "stance_foot_steps": int(stance.sum()),
            "centre_m": float(centre[stance].sum()), "min_m": float(mn[stance].sum()),
            "mean_m": float(mean[stance].sum()),
            "sphere_down_fraction": down.mean(axis=(0, 1)).tolist()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", type=float, default=20.0)
    ap.add_argument("--out", type=Path, default=Path("experiments/results/nao_slip_audit.json"))
    a = ap.parse_args()
    t0 = time.perf_counter()
    p = make_gait_problem("nao", backend="native", horizon=a.horizon)
    model = native_model(p.spec, float(p.slope_deg), p.accuracy)
    radius = float(model.geom_size[model.geom(p.spec.foot_geoms[0]).id, 0])
    normal = floor_normal(float(p.slope_deg)).astype(np.float64)
    rows = []
    for name, path in GAITS.items():
        sim = p.simulate(gait_vector(path))
        steps = int(round(sim["fall_time"] / p.spec.control_dt)) if sim["fell"] else None
        qpos = sim["qpos"][1 : (steps + 1) if steps else None]
        r = audit(soles_of(p, qpos), radius, normal)
        walked = max(float(sim["distance_m"]), 0.1)
        r |= {"gait": name, "file": path, "speed_mps": float(sim["speed_mps"]),
              "distance_m": float(sim["distance_m"]), "fell": bool(sim["fell"]),
              "foot_slip_m_metric": float(sim["quality"]["foot_slip_m"]),
              "per_m": {k: r[k] / walked for k in ("centre_m", "min_m", "mean_m")}}
        rows.append(r)
        print(json.dumps(r, indent=1))
    write_results(a.out, rows, horizon=a.horizon, world="nominal", backend="native",
                  seconds=time.perf_counter() - t0)


if __name__ == "__main__":
    main()
