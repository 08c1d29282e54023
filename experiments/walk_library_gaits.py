"""Draw the route walker's forward cells from a filled gait library (issue #32, item 3 to 4).

    python experiments/walk_library_gaits.py \
        experiments/results/gait_library/constrained_warp_20s/library_seed0.json

Reads one run seed's MAP-Elites archive (``gait_library.py`` writes ``library_seed<seed>.json``
with each cell's validation in worlds of the test stream of that run seed) and writes a walk
gait library (``eaco_jax/data/walk_gaits/nao_library.json`` by default) whose
``forward_cells`` the controller picks among each step cycle
(:func:`eaco_jax.gait.walk_route.pick_cell`). The rule was fixed before any walk with it:

* a cell qualifies when its gait never fell in its validation worlds, walks forward at
  ``--min-speed`` or more and turns at most ``--max-turn`` deg/s (the controller steers the
  cell itself) with a travel direction within ``--max-travel`` deg of its torso's heading;
* of the qualifying cells of each speed row, the one with the least constraint violation in
  its validation worlds (heat, current, slip, drift; the motor-credible one) is kept.

The turning gaits for turns on the spot are the fastest kept cell stepping in place at the
walk engine's turn-rate bound, as in ``nao_constrained``: no archive cell turns in place
without falling. The planning entry (the speed and yaw rate a planner prices) is the time
model ``walk_tune.py --gaits nao_library`` fitted on the tuning scenes in selection-stream
worlds (``--planning`` names its output), as it was fitted for ``nao_constrained``; without
``--planning`` the file has none (walk it with planned routes of another library).
``--start-ramp-s`` records the controller's start ramp chosen for these cells
(``experiments/walk_start.py`` on the tuning scenes) and ``--max-steer`` its steering bound
(``walk_tune.py`` on the corner scenes); ``eaco walk`` uses them unless told otherwise.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from eaco_jax.gait.walk_engine import PARAM_NAMES, UPPER
from eaco_jax.outputs import write_json

HERE = Path(__file__).resolve().parent
TURN = PARAM_NAMES.index("turn_rate")
STEP = PARAM_NAMES.index("step_length")


def qualifying(cells: list[dict], min_speed: float, max_turn: float,
               max_travel: float) -> list[dict]:
    """The cells the rule admits (never fell, fast enough, straight enough)."""
    out = []
    for c in cells:
        fwd, lat = c["test_forward_mps"], c["test_lateral_mps"]
        travel = math.degrees(math.atan2(lat, fwd))
        if (c["test_fall_rate"] == 0 and fwd >= min_speed and abs(c["test_turn_deg_s"]) <= max_turn
                and abs(travel) <= max_travel):
            out.append({**c, "travel_deg": travel})
    return out


def per_row(cells: list[dict]) -> list[dict]:
    """Of each speed row (the archive's first coordinate), the cell of least violation."""
    best: dict[int, dict] = {}
    for c in cells:
        row = c["coords"][0]
        if row not in best or c["test_violation"] < best[row]["test_violation"]:
            best[row] = c
    return sorted(best.values(), key=lambda c: c["test_forward_mps"])


def controller_entry(start_ramp_s: float | None, max_steer: float | None) -> dict:
    """The library file's ``controller`` entry: the settings chosen for these cells, each
    with the claim that chose it (none given: no entry)."""
    chosen, claims = {}, {}
    if start_ramp_s is not None:
        chosen["start_ramp_s"] = start_ramp_s
        claims["start_ramp_s"] = f"walk-start-ramp-library-{start_ramp_s:g}-falls"
    if max_steer is not None:
        chosen["max_steer"] = max_steer
        claims["max_steer"] = f"walk-library-corners-max-steer-{max_steer:g}-successes"
    return {"controller": {**chosen, "claims": claims}} if chosen else {}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("library", type=Path, help="a library_seed<seed>.json of gait_library.py")
    ap.add_argument("--min-speed", type=float, default=0.05)
    ap.add_argument("--max-turn", type=float, default=7.5)
    ap.add_argument("--max-travel", type=float, default=30.0)
    ap.add_argument("--planning", type=Path, default=None,
                    help="a walk_tune.py output whose nao_library row's time model to price")
    ap.add_argument("--start-ramp-s", type=float, default=None,
                    help="the controller's start_ramp_s for this library (walk_start.py)")
    ap.add_argument("--max-steer", type=float, default=None,
                    help="the controller's max_steer for this library (walk_tune.py on the "
                         "corner scenes)")
    ap.add_argument("--out", type=Path,
                    default=HERE.parent / "eaco_jax" / "data" / "walk_gaits" / "nao_library.json")
    args = ap.parse_args()
    lib = json.loads(args.library.read_text())
    kept = per_row(qualifying(lib["cells"], args.min_speed, args.max_turn, args.max_travel))
    if not kept:
        raise SystemExit(f"{args.library}: no cell qualifies")
    try:
        source = str(args.library.resolve().relative_to(HERE.parent))
    except ValueError:
        source = str(args.library)
    top = np.array([kept[-1]["params"][k] for k in PARAM_NAMES])
    bound = float(UPPER[TURN])
    turns = {}
    for name, sign in (("turn_left", 1.0), ("turn_right", -1.0)):
        v = top.copy()
        v[STEP], v[TURN] = 0.0, sign * bound
        turns[name] = {"from": f"the fastest cell {kept[-1]['coords']} with step_length 0, "
                               f"turn_rate {sign * bound:+g}", "vector": v.tolist()}
    planning = {}
    if args.planning is not None:
        tune = json.loads(args.planning.read_text())
        rows = [r for r in tune["configs"] if r["gaits"] == args.out.stem and not r["config"]]
        if len(rows) != 1 or not rows[0]["time_model"]:
            raise SystemExit(f"{args.planning}: no single {args.out.stem} row with a time model")
        tm = rows[0]["time_model"]
        planning = {"planning": {
            "speed_mps": round(tm["speed_mps"], 3),
            "yaw_rate_deg_s": round(tm["yaw_rate_deg_s"], 1),
            "from": f"{tune['command']} (the {args.out.stem} row's time_model: {tm['walks']} "
                    f"successful walks, tuning scenes, selection-stream worlds)",
            "speed_claim": "walk-library-plan-speed", "yaw_claim": "walk-library-plan-yaw-rate"}}
    write_json(args.out, {
        "robot": "nao",
        "source": (f"forward cells drawn from the MAP-Elites archive {source} (problem "
                   f"{lib['problem']}, run seed {lib['seed']}, {lib['horizon_s']} s rollouts) by "
                   f"experiments/walk_library_gaits.py: cells that never fell in their "
                   f"validation worlds, at least {args.min_speed} m/s, at most {args.max_turn} "
                   f"deg/s of turn and {args.max_travel} deg of travel direction; per speed row "
                   f"the least violation. The controller picks among them by speed each step "
                   f"cycle and steers the cell (eaco_jax.gait.walk_route.pick_cell). forward: "
                   f"the fastest cell; turn_left / turn_right: it stepping in place at the "
                   f"engine's turn-rate bound. Walk it with the spec's motors. Parameter order: "
                   f"eaco_jax.gait.walk_engine.PARAM_NAMES."),
        "gaits": {"forward": {"from": f"cell {kept[-1]['coords']}", "vector": top.tolist()},
                  **turns},
        "forward_cells": [{
            "cell": c["coords"], "vector": [c["params"][k] for k in PARAM_NAMES],
            "speed_mps": c["test_forward_mps"], "travel_deg": c["travel_deg"],
            "turn_deg_s": c["test_turn_deg_s"], "violation": c["test_violation"],
            "fall_rate": c["test_fall_rate"]} for c in kept],
        **planning,
        **controller_entry(args.start_ramp_s, args.max_steer),
    })
    for c in kept:
        print(f"cell {c['coords']}: {c['test_forward_mps']:.3f} m/s, travel "
              f"{c['travel_deg']:+.1f} deg, turn {c['test_turn_deg_s']:+.2f} deg/s, violation "
              f"{c['test_violation']:.2f}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
