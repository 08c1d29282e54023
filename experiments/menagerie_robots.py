"""The vendored Menagerie robots (and the NAO beside them): mass, standing for 2 s on native
MuJoCo holding the spec's standing pose, and MJX physics steps per second on this machine.

Writes ``experiments/results/menagerie_robots.json``. No optimisation, no random seeds: the
standing test is deterministic and the MJX timing steps a batch of copies of the standing state.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import jax
import mujoco
import numpy as np

from eaco_jax.gait.robot import load_model, load_robot, stand_qpos

RESULTS = Path(__file__).resolve().parent / "results"


def stand(name: str, seconds: float = 2.0) -> dict:
    """Hold ``stand_ctrl`` for ``seconds`` from the standing pose; torso drift and tilt."""
    spec = load_robot(name)
    model = load_model(spec)
    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(spec, model)
    data.ctrl[:] = spec.stand_ctrl
    mujoco.mj_forward(model, data)
    torso = model.body(spec.torso_body).id
    start = data.xpos[torso].copy()
    for _ in range(int(round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
    end = data.xpos[torso]
    up = data.xmat[torso].reshape(3, 3)[2, 2]
    return {"robot": name, "mass_kg": float(sum(model.body_mass)), "nu": int(model.nu),
            "seconds": seconds, "timestep": float(model.opt.timestep),
            "torso_start_z": float(start[2]), "torso_end_z": float(end[2]),
            "torso_drift_xy_m": float(np.linalg.norm(end[:2] - start[:2])),
            "tilt_deg": float(np.degrees(np.arccos(np.clip(up, -1, 1)))),
            "standing": bool(end[2] > spec.fall_height and up > np.cos(np.radians(10)))}


def mjx_rate(name: str, batch: int, steps: int) -> dict:
    """MJX physics steps/s: ``batch`` copies of the standing state stepped ``steps`` times."""
    from mujoco import mjx

    spec = load_robot(name)
    model = load_model(spec)
    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(spec, model)
    data.ctrl[:] = spec.stand_ctrl
    mx = mjx.put_model(model)
    dx = jax.vmap(lambda _: mjx.put_data(model, data))(np.arange(batch))

    @jax.jit
    def run(d):
        return jax.lax.fori_loop(0, steps, lambda _, x: jax.vmap(mjx.step, (None, 0))(mx, x), d)

    jax.block_until_ready(run(dx))  # compile
    t0 = time.perf_counter()
    out = jax.block_until_ready(run(dx))
    dt = time.perf_counter() - t0
    return {"robot": name, "batch": batch, "steps": steps, "seconds": dt,
            "steps_per_s": batch * steps / dt,
            "finite": bool(np.all(np.isfinite(np.asarray(out.qpos))))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--robots", default="op3,go2,nao")
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--out", default=str(RESULTS / "menagerie_robots.json"))
    args = ap.parse_args()
    names = args.robots.split(",")
    record = {"machine": platform.processor() or platform.machine(),
              "device": str(jax.devices()[0]), "jax": jax.__version__,
              "mujoco": mujoco.__version__,
              "stand": [stand(n) for n in names],
              "mjx": [mjx_rate(n, args.batch, args.steps) for n in names]}
    Path(args.out).write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps(record, indent=1))


if __name__ == "__main__":
    main()
