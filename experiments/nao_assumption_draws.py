"""How robust is the NAO's speed x endurance answer to the motor assumptions? Random draws.

The gaits of ``experiments/results/nao_feasibility.json``'s speed x endurance fronts (nominal
assumptions and the optimistic corner) walk ``--horizon`` seconds in the nominal world on
native MuJoCo (CPU, motor limits in the physics) under ``--draws`` sets of motor assumptions,
each drawn uniformly from the ranges in ``robots/nao.json`` ``motors.assumption_ranges`` (gear
efficiency, current limit, firmware limit, maximum winding temperature, winding share of the
thermal resistance, both thermal time constants per motor type; sampling seed ``--seed``).
For each gait: the share of draws under which it walks ten minutes from 25 C below the
firmware limit without a fall. Summary: the fastest gait that does so in at least half of the
draws, and in any draw.

    python experiments/nao_assumption_draws.py --out experiments/results/nao_assumption_draws.json
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from common import write_results

from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.robot import ROBOTS_DIR, load_robot
from eaco_jax.problems.gait import make_gait_problem


def draw_spec(rng: np.random.Generator, folder: Path, i: int):
    """A NAO spec whose assumed motor values are one uniform draw from their ranges."""
    raw = json.loads((ROBOTS_DIR / "nao.json").read_text())
    raw["xml"] = str(ROBOTS_DIR / raw["xml"])
    m = raw["motors"]
    rng_of = m["assumption_ranges"]
    drawn: dict = {}
    for k in ("gear_efficiency", "current_limit_frac_of_stall", "firmware_limit_c"):
        m[k] = drawn[k] = float(rng.uniform(*rng_of[k]))
    for k in ("max_winding_c", "rth_winding_share"):
        drawn[k] = float(rng.uniform(*rng_of[k]))
        for typ in m["types"].values():
            typ[k] = drawn[k]
    for k in ("tau_winding_s", "tau_housing_s"):
        for t, typ in m["types"].items():
            typ[k] = drawn[f"{k}_{t}"] = float(rng.uniform(*rng_of[k][t]))
    path = folder / f"nao_draw{i}.json"
    path.write_text(json.dumps(raw))
    return load_robot(str(path)), drawn


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0, help="sampling seed of the assumption draws")
    ap.add_argument("--horizon", type=float, default=20.0)
    ap.add_argument("--scan", type=Path, default=Path("experiments/results/nao_feasibility.json"))
    ap.add_argument("--out", type=Path,
                    default=Path("experiments/results/nao_assumption_draws.json"))
    a = ap.parse_args()
    t0 = time.perf_counter()
    scan = json.loads(a.scan.read_text())["summary"]
    gaits, seen = [], set()
    for r in scan["front"] + scan["corner_front"]:
        x = tuple(round(r["params"][n], 7) for n in we.PARAM_NAMES)
        if x not in seen:
            seen.add(x)
            gaits.append(x)
    xs = jnp.asarray(np.asarray(gaits, np.float32))
    rng = np.random.default_rng(a.seed)
    folder = Path(tempfile.mkdtemp())
    ok = np.zeros((a.draws, len(gaits)), bool)
    speed = np.zeros((a.draws, len(gaits)))
    draws = []
    for i in range(a.draws):
        spec, drawn = draw_spec(rng, folder, i)
        p = make_gait_problem(spec, backend="native", horizon=a.horizon)
        m = jax.device_get(jax.jit(lambda x, p=p: p.metrics(x, quality=True))(xs))
        limit = drawn["firmware_limit_c"]
        hot = np.max(np.asarray(m["winding_10min_c"]), axis=-1)
        ok[i] = (hot <= limit) & (np.asarray(m["fell"]) == 0)
        speed[i] = np.asarray(m["speed_mps"])
        draws.append({**drawn, "gaits_ok": int(ok[i].sum())})
        print(f"draw {i}: {ok[i].sum()} of {len(gaits)} gaits last ten minutes", flush=True)
    share = ok.mean(0)
    rows = [{"params": dict(zip(we.PARAM_NAMES, g, strict=True)),
             "speed_mps_mean": float(speed[:, j].mean()), "share_ten_minutes": float(share[j])}
            for j, g in enumerate(gaits)]
    fastest = lambda s: max((r["speed_mps_mean"] for r in rows  # noqa: E731
                             if r["share_ten_minutes"] >= s), default=None)
    write_results(a.out, rows, draws=draws, seed=a.seed,
                  seed_role="sampling of the assumption draws (no search)", horizon=a.horizon,
                  summary={"gaits": len(gaits), "draws": a.draws,
                           "fastest_ten_minutes_in_half_the_draws": fastest(0.5),
                           "fastest_ten_minutes_in_any_draw": fastest(1e-9),
                           "draws_with_any_gait_ok": int(np.sum(ok.any(1)))},
                  seconds=time.perf_counter() - t0)
    print(json.dumps(json.loads(a.out.read_text())["summary"], indent=1))


if __name__ == "__main__":
    main()
