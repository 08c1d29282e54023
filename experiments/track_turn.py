"""Does a gait turn at the rate it asks for? Open loop against ``Steering(track_turn=True)``.

A gait-library cell is the walk engine's gait at some commanded turn rate; open loop, the rate it
really turns at is whatever its joint errors make of that command, so the cell it lands in is a
noisy measurement. ``track_turn`` closes the heading loop on a heading that turns at the
commanded rate. This script walks one stored gait (default the stored flat gait) at several
commanded turn rates, open loop and tracking, in the same randomised worlds, and reports the
measured turn rate against the command, its spread over the worlds, forward speed and falls.

    python experiments/track_turn.py --worlds 16 --horizon 10 \\
        --out experiments/results/track_turn/flat_r32_native.json

Nothing is chosen here: the worlds are the test stream of ``--seed`` (default 29, which no
search or selection used).
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
import time
from pathlib import Path

import common as st
import jax.numpy as jnp
import numpy as np

from eaco_jax.gait.steer import Steering
from eaco_jax.gait.walk_engine import PARAM_NAMES
from eaco_jax.gait.worlds import RobustConfig, stream_key
from eaco_jax.problems.gait_library import make_gait_library_problem
from eaco_jax.runs.gait import params_vector, read_params_file

GAIT = "results/nao_constrained_warp/flat_r32/best_gait.json"


def measure(gait: Path, rates: list[float], worlds: int, seed: int, horizon: float,
            backend: str, target_noise: float, track: bool) -> list[dict]:
    """Per commanded rate [rad/s]: the measured turn rate over the worlds and the falls."""
    prob = make_gait_library_problem(
        backend=backend, horizon=horizon,
        robust=RobustConfig(R=worlds, aggregate="mean", seed=seed, target_noise=target_noise),
        steering=Steering(track_turn=True) if track else None)
    x = np.asarray(params_vector(read_params_file(str(gait)), prob.gait, str(gait)), np.float32)
    xs = np.stack([x] * len(rates))
    xs[:, PARAM_NAMES.index("turn_rate")] = rates
    m = prob.measure(jnp.asarray(xs), prob.gait.worlds(stream_key(seed, "test", 0), worlds))
    m = {k: np.asarray(v) for k, v in m.items()}
    rows = []
    for i, r in enumerate(rates):
        turn, fell = m["turn_deg_s"][i], m["fell"][i].astype(bool)
        err = turn - math.degrees(r)
        rows.append({"commanded_deg_s": math.degrees(r), "turn_deg_s_mean": float(turn.mean()),
                     "turn_deg_s_sd": float(turn.std(ddof=1)) if worlds > 1 else 0.0,
                     "abs_error_deg_s_mean": float(np.abs(err).mean()),
                     "abs_error_deg_s_max": float(np.abs(err).max()),
                     "forward_mps_mean": float(m["forward_mps"][i].mean()),
                     "falls": int(fell.sum()), "worlds": worlds})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gait", type=Path, default=Path(GAIT))
    ap.add_argument("--rates", type=float, nargs="+", default=[-0.2, -0.1, 0.0, 0.1, 0.2],
                    help="commanded turn rates, rad/s (the walk engine's box: +/-0.3)")
    ap.add_argument("--worlds", type=int, default=16)
    ap.add_argument("--seed", type=int, default=29)
    ap.add_argument("--horizon", type=float, default=10.0)
    ap.add_argument("--backend", default="native")
    ap.add_argument("--target-noise", type=float, default=0.000443)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    t0 = time.perf_counter()
    arms = {name: measure(a.gait, a.rates, a.worlds, a.seed, a.horizon, a.backend,
                          a.target_noise, name == "track") for name in ("open", "track")}
    print(f"{'commanded':>10s} {'open: turn (sd) |err|':>28s} {'track: turn (sd) |err|':>28s}"
          " falls open/track")
    for o, t in zip(arms["open"], arms["track"], strict=True):
        print(f"{o['commanded_deg_s']:9.2f}  {o['turn_deg_s_mean']:8.2f} "
              f"({o['turn_deg_s_sd']:.2f}) {o['abs_error_deg_s_mean']:6.2f}     "
              f"{t['turn_deg_s_mean']:8.2f} "
              f"({t['turn_deg_s_sd']:.2f}) {t['abs_error_deg_s_mean']:6.2f}     "
              f"{o['falls']}/{t['falls']}")
    doc = {"date": datetime.date.today().isoformat(),
           "command": "python experiments/track_turn.py " + " ".join(sys.argv[1:]),
           "gait": str(a.gait), "backend": a.backend, "horizon_s": a.horizon,
           "worlds": {"seed": a.seed, "stream": "test", "batch": 0, "n": a.worlds,
                      "target_noise": a.target_noise},
           "steering": Steering(track_turn=True).record(), "arms": arms,
           "seconds": time.perf_counter() - t0}
    if a.out is not None:
        st.write_results(a.out, [], **doc)
        print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
