"""Memory maps held by one process that compiles many distinct colony programs.

Each distinct static configuration (here: the number of ants) is a new compiled chunk and
initialiser; on XLA:CPU each holds memory maps of its own, and Linux kills nothing but lets
the next ``mmap`` fail once a process holds ``vm.max_map_count`` of them (XLA then crashes).
The driver keeps its compiled programs while the process holds at most half of that limit.
This counts ``/proc/self/maps`` after every ``--every`` programs.

    python experiments/program_maps.py --programs 80 --out experiments/results/program_maps.json
"""

from __future__ import annotations

import argparse
import datetime
import gc
from pathlib import Path

from common import write_results

import eaco_jax as ea
from eaco_jax.driver.programs import memory_maps
from eaco_jax.strategies import GraphEACO


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", type=int, default=80, help="distinct colony sizes to run")
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--instance", default="eil51")
    ap.add_argument("--out", type=Path, default=Path("experiments/results/program_maps.json"))
    args = ap.parse_args(argv)
    limit = memory_maps()[1]
    tsp = ea.problems.get(args.instance)
    gc.collect()
    rows = [{"programs": 0, "maps": memory_maps()[0]}]
    print(f"{'programs':>8} {'maps':>7} {'share of limit':>14}")
    print(f"{0:>8} {rows[0]['maps']:>7} {rows[0]['maps'] / limit:>14.3f}")
    for i in range(args.programs):
        ea.minimize(tsp, GraphEACO(num_ants=4 + i), seed=0, iterations=2)
        if (i + 1) % args.every == 0:
            gc.collect()
            rows.append({"programs": i + 1, "maps": memory_maps()[0]})
            print(f"{i + 1:>8} {rows[-1]['maps']:>7} {rows[-1]['maps'] / limit:>14.3f}",
                  flush=True)
    first = rows[1]
    write_results(args.out, rows, date=datetime.date.today().isoformat(),
                  command="python experiments/program_maps.py " + " ".join(argv or []),
                  max_map_count=limit, instance=args.instance,
                  maps_per_program=(first["maps"] - rows[0]["maps"]) / first["programs"],
                  peak_maps=max(r["maps"] for r in rows),
                  note="a program is one colony size: its compiled chunk and initialiser")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
