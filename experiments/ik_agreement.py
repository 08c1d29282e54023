"""Generic leg IK vs the NAO's analytic IK on the stored gait, and the generic IK's speed.

Agreement: the walk engine's ankle targets of ``results/nao_best_gait.json`` over the ramp second
and ``--periods`` steady periods (every control step, both legs) are solved by the analytic
``leg_ik`` and by the generic damped-least-squares IK on the MJCF's leg chains (from the
standing pose); both solutions go through the chain's forward kinematics. Reported: the largest
and mean ankle distance between the two and the largest joint-angle difference. No seeds: the
gait is fixed, nothing is random.

Speed: one control step's IK for a colony (``--ants`` x 2 legs, position + sole orientation),
jitted, median of ``--repeats`` calls, beside the analytic IK of the same targets.

    python experiments/ik_agreement.py --out experiments/results/ik_agreement.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import common
import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.gait import ik_generic as g
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.ik import leg_ik
from eaco_jax.gait.robot import load_model, load_robot


def rot_z(yaw: jnp.ndarray) -> jnp.ndarray:
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    o, z = jnp.ones_like(yaw), jnp.zeros_like(yaw)
    return jnp.stack([jnp.stack([c, -s, z], -1), jnp.stack([s, c, z], -1),
                      jnp.stack([z, z, o], -1)], -2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    results = common.REPO / "experiments/results"
    ap.add_argument("--gait", type=Path, default=results / "nao_best_gait.json")
    ap.add_argument("--periods", type=float, default=4.0)
    ap.add_argument("--iterations", type=int, default=12, help="IK iterations (fixed)")
    ap.add_argument("--ants", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--out", type=Path, default=results / "ik_agreement.json")
    args = ap.parse_args()

    spec = load_robot("nao")
    model = load_model(spec)
    found = [g.extract_chain(model, spec.torso_body, f) for f in ("l_foot", "r_foot")]
    chains = g.stack_chains([c for c, _ in found])
    stand = jnp.asarray([[spec.stand_ctrl[spec.joint_names.index(n)] for n in names]
                         for _, names in found])
    hip = jnp.stack([c.offset_pos[0] for c, _ in found])
    gait = json.loads(args.gait.read_text())
    v = jnp.asarray(gait["vector"], jnp.float32)
    horizon = we.RAMP_TIME + args.periods * float(gait["params"]["period"])
    t = jnp.arange(0.0, horizon, spec.control_dt)
    feet = jax.jit(jax.vmap(lambda tt: we.biped_feet(v, tt, spec)))(t)
    ankle = feet.delta + jnp.array([0.0, 0.0, -(spec.geom("stand_hip_height")
                                                - spec.geom("foot_height"))])
    yaw_sign = jnp.array([1.0, -1.0])  # RHipYawPitch turns about -z

    def analytic(a, y):
        q = leg_ik(a, y, spec.geom("thigh"), spec.geom("tibia"))
        return q.at[..., 0].multiply(yaw_sign)

    def generic(a, y):
        solve = jax.vmap(lambda c, p, q0, r: g.solve(c, p, q0, r, args.iterations)[0])
        return jax.vmap(solve, in_axes=(None, 0, None, 0))(chains, hip + a, stand, rot_z(y))

    fk = jax.jit(jax.vmap(jax.vmap(lambda c, q: g.fk(c, q)[0]), in_axes=(None, 0)))
    q_ref = jax.jit(analytic)(ankle, feet.yaw)
    q_gen = jax.jit(generic)(ankle, feet.yaw)
    gap = np.asarray(jnp.linalg.norm(fk(chains, q_gen) - fk(chains, q_ref), axis=-1))
    target_gap = np.asarray(jnp.linalg.norm(fk(chains, q_gen) - (hip + ankle), axis=-1))
    dq = np.asarray(jnp.abs(q_gen - q_ref))
    agreement = {
        "steps": int(len(t)), "legs": 2, "seconds": float(horizon),
        "max_ankle_gap_mm": float(gap.max() * 1e3), "mean_ankle_gap_mm": float(gap.mean() * 1e3),
        "max_target_gap_mm": float(target_gap.max() * 1e3),
        "max_joint_gap_mrad": float(dq.max() * 1e3),
    }

    # speed: one control step for a colony, both legs, from the colony's own targets
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(t), args.ants)
    a_col, y_col = ankle[idx], feet.yaw[idx]
    gen = jax.jit(generic)
    ana = jax.jit(analytic)
    first_g, med_g = common.timed(lambda: gen(a_col, y_col), args.repeats)
    first_a, med_a = common.timed(lambda: ana(a_col, y_col), args.repeats)
    rows = [
        {"ik": "generic", "ants": args.ants, "legs": 2, "iterations": args.iterations,
         "first_call_s": first_g, "median_s": med_g, "us_per_leg": med_g / (2 * args.ants) * 1e6},
        {"ik": "analytic", "ants": args.ants, "legs": 2, "first_call_s": first_a,
         "median_s": med_a, "us_per_leg": med_a / (2 * args.ants) * 1e6},
    ]
    common.write_results(args.out, rows, agreement=agreement, gait=str(args.gait.name),
                         periods=args.periods, iterations=args.iterations)
    print(json.dumps({"agreement": agreement, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
