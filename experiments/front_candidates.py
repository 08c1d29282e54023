"""Gaits from a speed x endurance front, chosen on worlds apart from the ones that found them.

``gait_fronts.py`` leaves each seed's front (both arms) rescored in a few selection worlds.
``write`` turns every front point at or past ``--min-speed`` and ``--min-endurance`` into a gait
record (the front's ``--init`` gait with the point's vector, and ``--seed``: a run seed whose
streams no search used), so ``nao_gait_table.py`` walks it. ``pick`` reads their tables on that
seed's *selection* stream and applies the rule fixed before any was run:

1. fewest worlds failing any constraint (falls included), then
2. fewest falls, then
3. the highest mean speed.

The chosen gait is then walked on the same seed's *test* stream, which chose nothing.

A speed x CoT front says nothing of heat, and holds many points past ``--min-speed``: from it
``write`` takes, per arm and run seed, the one point at or past ``--min-speed`` with the lowest
electrical cost of transport (the most economical fast gait of each front).

    cd experiments; F=results/gait_fronts; C=$F/fast_candidates
    python front_candidates.py write $F/endurance_steer_mjx_20s_128x4_g16.json \\
        --min-speed 0.35 --min-endurance 10 --seed 27 --out $C
    for f in $C/c??.json; do JAX_PLATFORMS=cpu python nao_gait_table.py $f --worlds 64 \\
        --stream selection --out ${f%.json}_sel64.json; done
    python front_candidates.py pick $C
    JAX_PLATFORMS=cpu python nao_gait_table.py $C/cNN.json --worlds 400   # the chosen one
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from eaco_jax.gait.robot import load_robot
from eaco_jax.problems.gait import param_names


def write(fronts: Path, min_speed: float, min_endurance: float, seed: int, out: Path) -> list:
    """One gait record per qualifying front point; returns their rows."""
    d = json.loads(fronts.read_text())
    second = d["problem"]["second"]
    if second not in ("endurance", "cot"):
        raise SystemExit(f"{fronts}: a speed x endurance or speed x CoT front is needed")
    names = param_names(load_robot("nao"))
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for arm, a in d["arms"].items():
        for s in a["seeds"]:
            points = list(zip(s["rescored_front"], s["rescored_front_x"], strict=True))
            if second == "cot":  # per front, the most economical point past min_speed
                fast = [p for p in points if -p[0][0] >= min_speed]
                points = [min(fast, key=lambda p: p[0][1])] if fast else []
            for f, x in points:
                speed = -f[0]
                endurance = -f[1] if second == "endurance" else None
                if speed < min_speed or (endurance is not None and endurance < min_endurance):
                    continue
                name = f"c{len(rows):02d}"
                rec = {"robot": "nao", "backend": d["problem"]["backend"],
                       "horizon": d["problem"]["horizon_s"], "direction": 0.0, "slope": 0.0,
                       "steering": d["problem"]["steering"], "seed": seed,
                       "robust": {"target_noise": d["problem"]["target_noise"]},
                       "params": dict(zip(names, x, strict=True)), "vector": list(x),
                       "front": {"file": str(fronts), "arm": arm, "run_seed": s["seed"],
                                 "speed": speed, "endurance_min": endurance,
                                 "cot": f[1] if second == "cot" else None,
                                 "scored_on": d["seeds"]["scoring"]}}
                if Path(d["problem"]["init"]).is_file():  # the gait the front was searched around
                    rec["init"] = d["problem"]["init"]
                (out / f"{name}.json").write_text(json.dumps(rec, indent=1))
                rows.append({"name": name, "arm": arm, "run_seed": s["seed"],
                             "speed": speed, "endurance_min": endurance,
                             "cot": f[1] if second == "cot" else None})
    (out / "candidates.json").write_text(json.dumps(
        {"fronts": str(fronts), "second": second, "min_speed": min_speed,
         "min_endurance": min_endurance if second == "endurance" else None,
         "seed": seed, "candidates": rows}, indent=1))
    return rows


def pick(folder: Path, suffix: str = "_sel64.json") -> dict:
    """The rule of the module docstring over the candidates' selection tables."""
    rows = []
    for t in sorted(folder.glob(f"c*{suffix}")):
        r = json.loads(t.read_text())
        if r["stream"] != "selection":
            raise SystemExit(f"{t}: a selection-stream table is needed, got {r['stream']}")
        rows.append({"name": t.name.removesuffix(suffix), "failing": r["worlds"]
                     - r["all_constraints_met"], "falls": r["falls"]["falls"],
                     "speed": r["speed_mean"], "worlds": r["worlds"], "seed": r["seed"]})
    if not rows:
        raise SystemExit(f"no candidate tables c*{suffix} in {folder}")
    order = sorted(rows, key=lambda r: (r["failing"], r["falls"], -r["speed"]))
    res = {"rule": "fewest worlds failing any constraint, then fewest falls, then highest "
                   "mean speed (selection stream)", "chosen": order[0]["name"], "ranked": order}
    (folder / "pick.json").write_text(json.dumps(res, indent=1))
    return res


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    w = sub.add_parser("write")
    w.add_argument("fronts", type=Path)
    w.add_argument("--min-speed", type=float, default=0.35)
    w.add_argument("--min-endurance", type=float, default=10.0)
    w.add_argument("--seed", type=int, required=True)
    w.add_argument("--out", type=Path, required=True)
    p = sub.add_parser("pick")
    p.add_argument("folder", type=Path)
    a = ap.parse_args(argv)
    if a.cmd == "write":
        rows = write(a.fronts, a.min_speed, a.min_endurance, a.seed, a.out)
        print(f"{len(rows)} candidates in {a.out}")
    else:
        res = pick(a.folder)
        for r in res["ranked"]:
            print(r)
        print(f"chosen: {res['chosen']}")


if __name__ == "__main__":
    main()
