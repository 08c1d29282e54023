"""Where do the motor constraints bind for the NAO? A scan of the walk engine on native MuJoCo.

Every gait walks ``--horizon`` seconds in the nominal world (CPU, native MuJoCo, the motor limits
in the physics) and is scored on speed and on the motor model's projection to continuous walking
(:mod:`eaco_jax.gait.motors`): the hottest winding after ten minutes (mean loss plus the ripple
bound), the minutes until the first winding reaches the firmware limit, the steady state, and
the slip and drift constraints of :mod:`eaco_jax.gait.constraints`.

Two sets of gaits (sampling seed ``--seed``, a scan seed: nothing here is a search):

* ``grid``: the stored gait (``experiments/results/nao_best_gait.json``) with stance height
  (``hip_height``: knee bend), step length, period and sideways sway (CoM sway) set on a grid;
* ``random``: ``--random`` gaits drawn uniformly from the walk engine's box, with direction
  and turn rate 0;
* ``grid-flat``: the same grid with the roll compensations (``hip_roll_comp``,
  ``ankle_roll_comp``) 0;
* ``stand``: standing in the stored gait's posture at each stance height (no step, no lift, no
  sway, no arm swing, no roll compensations): the floor under any gait of that stance. Not
  counted as a gait that walks. The stored gait's roll compensations would keep acting with both
  feet down (the hip-roll one follows the stepping rhythm), which pushes the legs against each
  other (``experiments/nao_standing_heat.py``); those postures are in the summary's
  ``standing_with_roll_comp_10min_max_c``.

Then every gait that did not fall is walked again under the optimistic corner of the
documented assumption ranges (``robots/nao.json`` ``motors.assumption_ranges``: gear efficiency
0.85, maximum winding temperature 85 C, firmware limit 80 C, the longest thermal time
constants, current limit = the stall current): ``corner`` rows. A gait infeasible there is
infeasible anywhere in the ranges (each of these moves lowers the temperatures or raises the
limit; the gear efficiency also lifts the driving torque cap, so the gait's motion changes a
little).

The targets reach the motors as the spec says (the NAO's: interpolated linearly between control
steps, ``motors.interpolate_targets``); ``--held-targets`` holds them for each control step, the
model before that (for the comparison in docs/motors.md).

Writes every gait's row and the speed x endurance front (gaits that do not fall; for each
gait, no other walks faster with a longer endurance) to ``--out``.

    python experiments/nao_feasibility.py --random 256
    python experiments/nao_feasibility.py --random 256 --held-targets \
        --out experiments/results/nao_feasibility_held.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from common import write_results

from eaco_jax.gait import constraints as gc
from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.motors import motor_model
from eaco_jax.problems.gait import make_gait_problem

GRID = {
    "hip_height": (0.19, 0.20, 0.21, 0.22, 0.23, 0.24),
    "step_length": (0.02, 0.05, 0.08, 0.11, 0.14),
    "period": (0.3, 0.4, 0.55, 0.7),
    "lateral_sway": (0.0, 0.0125, 0.03),
}
CORNER = {"gear_efficiency": 0.85, "firmware_limit_c": 80.0, "current_limit_frac_of_stall": 1.0}
CORNER_TYPES = {"max_winding_c": 85.0, "tau_winding_s": "hi", "tau_housing_s": "hi"}
FLAT = ("hip_roll_comp", "ankle_roll_comp")
LEGS = ("HipYawPitch", "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll")


def rows_of(p, xs: np.ndarray, kind: str, batch: int) -> list[dict]:
    """Metrics of gaits ``xs`` ``(m, dim)`` in batches (one native rollout call each)."""
    names = p.spec.joint_names
    run = jax.jit(lambda x: p.metrics(x, quality=True))
    out = []
    for s in range(0, len(xs), batch):
        x = jnp.asarray(xs[s : s + batch], jnp.float32)
        m = jax.device_get(run(x))
        for i in range(x.shape[0]):
            t10 = np.asarray(m["winding_10min_c"][i])
            steady = np.asarray(m["winding_steady_c"][i])
            walked = max(float(m["distance_m"][i]), gc.SLIP_MIN_DISTANCE)
            hot = int(np.argmax(t10))
            end = float(m["min_endurance_min"][i])
            out.append({
                "kind": kind,
                "params": dict(zip(we.PARAM_NAMES, map(float, xs[s + i]), strict=True)),
                "speed_mps": float(m["speed_mps"][i]), "fell": bool(m["fell"][i] > 0),
                "distance_m": float(m["distance_m"][i]),
                "drift_deg": float(m["drift_deg"][i]),
                "slip_per_m": float(m["foot_slip_m"][i]) / walked,
                "peak_current_max_frac": float(m["peak_current_max_frac"][i]),
                "winding_10min_max_c": float(t10.max()), "hottest_joint": names[hot],
                "winding_steady_max_c": float(steady.max()),
                "endurance_min": end if np.isfinite(end) else None,
                "legs_10min_c": {r: float(max(t10[j] for j, n in enumerate(names)
                                              if n.endswith(r))) for r in LEGS},
            })
    return out


def variant_spec(folder: Path, corner: bool, held: bool):
    """The NAO spec at the optimistic corner of its assumption ranges (``corner``, see the
    docstring) and / or with its targets held for each control step (``held``: no
    ``motors.interpolate_targets``), written to ``folder``."""
    from eaco_jax.gait.robot import ROBOTS_DIR, load_robot

    raw = json.loads((ROBOTS_DIR / "nao.json").read_text())
    raw["xml"] = str(ROBOTS_DIR / raw["xml"])
    m = raw["motors"]
    if corner:
        m.update(CORNER)
        for t, typ in m["types"].items():
            for k, v in CORNER_TYPES.items():
                typ[k] = m["assumption_ranges"][k][t][1] if v == "hi" else v
    if held:
        m["interpolate_targets"] = False
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"nao{'_corner' if corner else ''}{'_held' if held else ''}.json"
    path.write_text(json.dumps(raw))
    return load_robot(str(path))


def best_endurance(rows: list[dict], speed: float) -> float | None:
    """The longest endurance (min) of a gait that walks at least ``speed`` without a fall
    (None if none does; a gait that never reaches the limit would be inf, written None)."""
    ok = [r for r in rows if not r["fell"] and r["speed_mps"] >= speed and r["kind"] != "stand"]
    if not ok:
        return None
    return max((r["endurance_min"] if r["endurance_min"] is not None else float("inf"))
               for r in ok)


def front(rows: list[dict]) -> list[dict]:
    """Non-falling gaits no other beats on both speed and endurance (inf = never)."""
    ok = [r for r in rows if not r["fell"] and r["speed_mps"] > 0]
    end = lambda r: float("inf") if r["endurance_min"] is None else r["endurance_min"]  # noqa: E731
    keep = [r for r in ok if not any(
        (o["speed_mps"] >= r["speed_mps"] and end(o) >= end(r)) and
        (o["speed_mps"] > r["speed_mps"] or end(o) > end(r)) for o in ok)]
    return sorted(keep, key=lambda r: r["speed_mps"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", type=float, default=20.0)
    ap.add_argument("--random", type=int, default=512)
    ap.add_argument("--seed", type=int, default=0, help="sampling seed of the random gaits")
    ap.add_argument("--batch", type=int, default=120)
    ap.add_argument("--out", type=Path, default=Path("experiments/results/nao_feasibility.json"))
    ap.add_argument("--held-targets", action="store_true",
                    help="hold each control step's targets for its physics steps (the model "
                         "before nao.json's motors.interpolate_targets)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    import tempfile

    folder = Path(tempfile.mkdtemp())
    p = make_gait_problem(variant_spec(folder, False, True) if a.held_targets else "nao",
                          backend="native", horizon=a.horizon)
    stored = np.asarray(json.loads(Path("experiments/results/nao_best_gait.json").read_text())
                        ["vector"], np.float32)
    idx = {n: we.PARAM_NAMES.index(n) for n in GRID}
    grid = []
    for values in itertools.product(*GRID.values()):
        x = stored.copy()
        for n, v in zip(GRID, values, strict=True):
            x[idx[n]] = v
        grid.append(x)
    rng = np.random.default_rng(a.seed)
    lo, hi = np.asarray(p.lower), np.asarray(p.upper)
    rand = lo + rng.random((a.random, p.dim)) * (hi - lo)
    for n in ("direction", "turn_rate"):
        rand[:, we.PARAM_NAMES.index(n)] = 0.0
    flat = np.asarray(grid).copy()
    for n in FLAT:
        flat[:, we.PARAM_NAMES.index(n)] = 0.0
    stand = []
    for h in GRID["hip_height"]:
        x = stored.copy()
        for n, v in (("hip_height", h), ("step_length", 0.0), ("foot_lift", 0.0),
                     ("lateral_sway", 0.0), ("arm_swing", 0.0)):
            x[we.PARAM_NAMES.index(n)] = v
        stand.append(x)
    stand_comp = np.asarray(stand)
    stand_flat = stand_comp.copy()
    for n in FLAT:
        stand_flat[:, we.PARAM_NAMES.index(n)] = 0.0
    rows = rows_of(p, np.asarray(grid), "grid", a.batch)
    rows += rows_of(p, flat, "grid-flat", a.batch)
    rows += rows_of(p, rand.astype(np.float32), "random", a.batch)
    rows += rows_of(p, stand_flat, "stand", a.batch)
    comp_rows = rows_of(p, stand_comp, "stand-roll-comp", a.batch)
    limit = gc.limits(motor_model(p.spec), a.horizon)
    pc = make_gait_problem(variant_spec(folder, True, a.held_targets), backend="native",
                           horizon=a.horizon)
    walking = np.asarray([[r["params"][n] for n in we.PARAM_NAMES] for r in rows
                          if not r["fell"] and r["kind"] != "stand"], np.float32)
    corner = rows_of(pc, walking, "corner", a.batch)
    climit = gc.limits(motor_model(pc.spec), a.horizon)
    gaits = [r for r in rows if r["kind"] != "stand"]
    feasible = [r for r in gaits if not r["fell"] and r["winding_10min_max_c"] <=
                limit["endurance"] and r["slip_per_m"] <= gc.SLIP_PER_M and
                r["drift_deg"] <= limit["drift"]]
    endurance_only = [r for r in gaits if not r["fell"] and r["winding_10min_max_c"] <=
                      limit["endurance"]]
    best = lambda rs: max(rs, key=lambda r: r["speed_mps"]) if rs else None  # noqa: E731
    corner_ok = [r for r in corner if not r["fell"] and r["winding_10min_max_c"] <=
                 climit["endurance"]]
    by_height = lambda rs, kind: {  # noqa: E731
        f"{r['params']['hip_height']:.2f}": r["winding_10min_max_c"] for r in rs
        if r["kind"] == kind}
    standing = by_height(rows, "stand")
    write_results(
        a.out, rows + comp_rows + corner, horizon=a.horizon, seed=a.seed,
        targets="held" if a.held_targets else "interpolated",
        seed_role="sampling (scan, no search)",
        grid={k: list(v) for k, v in GRID.items()}, limits=limit,
        corner={"motors": CORNER, "types": CORNER_TYPES, "limits": climit},
        summary={
            "standing_10min_max_c": standing,
            "standing_hottest_joint": {f"{r['params']['hip_height']:.2f}": r["hottest_joint"]
                                       for r in rows if r["kind"] == "stand"},
            "standing_with_roll_comp_10min_max_c": by_height(comp_rows, "stand-roll-comp"),
            "grid_flat_endurance_ok": sum(r["kind"] == "grid-flat" for r in endurance_only),
            "grid_flat_not_fallen": sum(r["kind"] == "grid-flat" and not r["fell"]
                                        for r in rows),
            "grid_not_fallen": sum(r["kind"] == "grid" and not r["fell"] for r in rows),
            "best_endurance_min_at_025": best_endurance(rows, 0.25),
            "corner_best_endurance_min_at_025": best_endurance(corner, 0.25),
            "best_endurance_min_at_015": best_endurance(rows, 0.15),
            "corner_best_endurance_min_at_015": best_endurance(corner, 0.15),
            "corner_endurance_ok": len(corner_ok),
            "corner_fastest_endurance_ok": best(corner_ok),
            "corner_front": front(corner),
            "gaits": len(gaits), "not_fallen": sum(not r["fell"] for r in gaits),
            "endurance_ok": len(endurance_only), "all_nominal_constraints_ok": len(feasible),
            "fastest_endurance_ok": best(endurance_only), "fastest_feasible": best(feasible),
            "fastest_walking": best([r for r in gaits if not r["fell"]]),
            "front": front(gaits),
        },
        seconds=time.perf_counter() - t0)
    s = json.loads(a.out.read_text())["summary"]
    print(json.dumps({k: v for k, v in s.items() if "front" not in k}, indent=1)[:4000])
    for r in s["front"] + [{"speed_mps": 0, "endurance_min": "corner:",
                            "winding_10min_max_c": 0, "hottest_joint": "",
                            "params": {"hip_height": 0, "step_length": 0, "period": 0}}] + \
            s["corner_front"]:
        print(f"{r['speed_mps']:.3f} m/s  endurance {r['endurance_min']} min  "
              f"T10 {r['winding_10min_max_c']:.0f} C ({r['hottest_joint']})  "
              f"hip {r['params']['hip_height']:.3f} step {r['params']['step_length']:.3f} "
              f"period {r['params']['period']:.2f}")


if __name__ == "__main__":
    main()
