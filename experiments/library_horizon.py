"""What rollout horizon a constrained gait library needs: the stored constrained flat gait and
its stepping-in-place turns, scored as cells of the constrained library, over horizons.

A MAP-Elites cell's gait is judged from one short rollout per world
(``make_gait_library_problem(..., constrained=True)``). The constraints were written for 20 s
walks (:mod:`eaco_jax.gait.constraints`), and the start-up from standing weighs more in a
shorter one. This script walks gaits that are known to hold them over 20 s (the stored flat gait
``flat_r32``; the route walker's turns, the same gait with ``step_length`` 0 and
``turn_rate`` +/-0.3) in the TEST stream's worlds of ``--seed`` at each ``--horizons`` value and
records each constraint's worst-world value and the violation. A horizon at which the flat
gait fails is too short for a constrained library.

    python experiments/library_horizon.py --horizons 3 5 10 20 --worlds 16

Writes ``results/gait_library/library_horizon.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from pathlib import Path

import common as st
import numpy as np

import eaco_jax as ea
from eaco_jax.gait.worlds import RobustConfig
from eaco_jax.problems.gait_library import make_gait_library_problem, validate
from eaco_jax.runs.gait import params_vector, read_params_file

RESULTS = Path(__file__).resolve().parent / "results" / "gait_library"
FLAT = (Path(__file__).resolve().parent / "results" / "nao_constrained_warp" / "flat_r32"
        / "best_gait.json")
WALK_GAITS = Path(ea.__file__).resolve().parent / "data" / "walk_gaits" / "nao_constrained.json"


def gaits(problem, init: Path) -> dict[str, np.ndarray]:
    """The flat gait, and the route walker's turning gaits (nao_constrained.json's turn
    entries: the flat gait with ``step_length`` 0 and ``turn_rate`` +/-0.3)."""
    flat = params_vector(read_params_file(init), problem.gait, str(init))
    lib = json.loads(WALK_GAITS.read_text())
    out = {"flat": np.asarray(flat, np.float32)}
    for mode in ("turn_left", "turn_right"):
        out[mode] = np.asarray(lib["gaits"][mode]["vector"], np.float32)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--horizons", type=float, nargs="+", default=[3.0, 5.0, 10.0, 20.0])
    ap.add_argument("--worlds", type=int, default=16, help="test-stream worlds per gait")
    ap.add_argument("--seed", type=int, default=31, help="run seed of the test stream")
    ap.add_argument("--init", type=Path, default=FLAT)
    ap.add_argument("--backend", default="native")
    ap.add_argument("--target-noise", type=float, default=None,
                    help="joint-target noise std of the worlds, rad (default: RobustConfig's; "
                    "the encoders' quantisation: 0.000443)")
    ap.add_argument("--out", type=Path, default=RESULTS / "library_horizon.json")
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = []
    for h in args.horizons:
        noise = {} if args.target_noise is None else {"target_noise": args.target_noise}
        prob = make_gait_library_problem(backend=args.backend, horizon=h, constrained=True,
                                         robust=RobustConfig(R=1, aggregate="mean", **noise))
        gs = gaits(prob, args.init)
        v = validate(prob, np.stack(list(gs.values())), trials=args.worlds, seed=args.seed,
                     chunk=len(gs))
        for j, name in enumerate(gs):
            row = {"horizon_s": h, "gait": name,
                   **{k: float(a[j]) for k, a in v.items()},
                   "feasible": bool(v["violation"][j] <= 0)}
            rows.append(row)
            print(f"{h:5.1f} s {name:10s} violation {row['violation']:8.3f}  "
                  + "  ".join(f"{k} {row[f'{k}_worst']:.3f}" for k in prob.constraint_names),
                  flush=True)
    st.write_results(args.out, rows, date=datetime.date.today().isoformat(),
                     command="python experiments/library_horizon.py " + " ".join(sys.argv[1:]),
                     seeds={"test": f"test stream of run seed {args.seed}, batch 0, "
                            f"{args.worlds} worlds (no search chose on it)"},
                     init=str(args.init),
                     target_noise=args.target_noise or RobustConfig().target_noise,
                     seconds=time.perf_counter() - t0,
                     versions={"eaco_jax": ea.__version__})
    print(f"wrote {args.out} ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
