"""What becomes of a focused colony's ants: how many leave the best tour changed, how many
improve it, and how much of that merging keeps (issue 33).

A colony with ``--max-new-edges`` builds each ant from the best tour and repairs it with the
local search. This runs the colony ``--warm`` iterations on a random uniform instance of
``tsp_large.py`` (a selection instance: nothing is reported on it), then, from that state,
asks ``--asks`` fresh colonies (keys 0, 1, ...) for each ``--arm`` and counts per ask: the ants
whose tour differs from the best tour (any city with other neighbours), the ants shorter than
it, the best ant's gain, and the gain and number of ants of
:func:`eaco_jax.ops.tour_merge.merge_improvements` over all ants. Lengths are the problem's
exact ones.

    python experiments/tsp_ant_outcomes.py --size 10000 --warm 60 --asks 3 \\
        --arm moves32="moves 32" --arm moves128="moves 128" --arm or3opt32="moves-or3opt 32"
"""

from __future__ import annotations

import argparse
import datetime
import json
import time
from pathlib import Path

import jax
import numpy as np
from common import write_results
from tsp_large import random_instance

import eaco_jax as ea
from eaco_jax.ops.local_search import changed_cities
from eaco_jax.ops.tour_merge import merge_improvements
from eaco_jax.problems import load_tsplib
from eaco_jax.strategies.graph_eaco import GraphEACO

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_large" / "ant_outcomes.json"


def colony(construction: str, max_new_edges: int, ants: int) -> GraphEACO:
    """The GPU's sparse colony (batched or-2opt focused on 128 cities a step, MMAS)."""
    return GraphEACO(num_ants=ants, local_search="or-2opt", max_new_edges=max_new_edges,
                     construction=construction, ls_focus_width=128, preset="mmas")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=10000)
    ap.add_argument("--instance-seed", type=int, default=1)
    ap.add_argument("--ants", type=int, default=96)
    ap.add_argument("--warm", type=int, default=60, help="iterations before the asks")
    ap.add_argument("--asks", type=int, default=3)
    ap.add_argument("--arm", action="append", required=True,
                    help='LABEL="CONSTRUCTION MAX_NEW_EDGES" (repeat)')
    ap.add_argument("--work", type=Path, default=Path("/tmp/tsp_equal_iterations"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    a.work.mkdir(parents=True, exist_ok=True)
    problem = load_tsplib(str(random_instance(a.work, a.size, a.instance_seed)), sparse=True)
    warm = ea.minimize(problem, colony("moves", 32, a.ants), seed=0, iterations=a.warm).state
    ref = np.asarray(warm.best_solution)
    ref_length = float(problem.exact_length(ref))
    rows = []
    for spec in a.arm:
        label, _, rest = spec.partition("=")
        construction, mne = rest.split()
        ask = jax.jit(colony(construction, int(mne), a.ants).ask)
        for k in range(a.asks):
            t0 = time.perf_counter()
            tours, _ = ask(jax.random.PRNGKey(k), warm, problem)
            tours = np.asarray(jax.block_until_ready(tours))
            seconds = time.perf_counter() - t0
            differ = np.asarray(changed_cities(tours, warm.best_solution)).any(axis=1)
            lengths = np.array([problem.exact_length(t) for t in tours])
            _, gain, merged, _ = merge_improvements(warm.best_solution, tours, problem.dist,
                                                    a.ants)
            row = {"arm": label, "construction": construction, "max_new_edges": int(mne),
                   "key": k, "ants": a.ants, "differ": int(differ.sum()),
                   "improve": int((lengths < ref_length).sum()),
                   "best_gain": ref_length - float(lengths.min()),
                   "merged_gain": float(gain), "merged_ants": int(merged),
                   "seconds": seconds, "first_call_compiles": k == 0}
            rows.append(row)
            print(json.dumps(row), flush=True)
    summary = {}
    for label in dict.fromkeys(r["arm"] for r in rows):
        rs = [r for r in rows if r["arm"] == label]
        timed = [r["seconds"] for r in rs if not r["first_call_compiles"]]
        summary[label] = {
            key: sum(r[key] for r in rs) / len(rs)
            for key in ("differ", "improve", "best_gain", "merged_gain", "merged_ants")}
        summary[label]["merged_over_best_gain"] = (
            sum(r["merged_gain"] for r in rs) / max(sum(r["best_gain"] for r in rs), 1.0))
        summary[label]["seconds_per_ask"] = sum(timed) / len(timed) if timed else None
    print(json.dumps(summary, indent=1))
    write_results(a.out, rows, date=datetime.date.today().isoformat(),
                  command="tsp_ant_outcomes.py " + " ".join(argv if argv is not None
                                                            else __import__("sys").argv[1:]),
                  summary=summary, reference_length=ref_length, warm_iterations=a.warm,
                  seeds={"instance": a.instance_seed, "run": 0,
                         "role": "selection instance: chooses, reports nothing"})
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
