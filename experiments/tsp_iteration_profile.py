"""Where one iteration of the sparse GPU colony spends its time (issue 33).

Runs the colony of ``eaco tsp``'s sparse GPU row (``--ants`` focused ants built as moves from
the best tour, the row's construction for the size unless ``--construction`` and
``--max-new-edges`` say otherwise, the batched or-2opt focused on 128 cities a step, the best
ants' improvements merged, MMAS) ``--warm`` iterations on a random uniform selection instance of
``tsp_large.py`` (nothing is reported on it), then times, from that state, each part of an
iteration as its own compiled call (warm, the median of ``--repeats``): the whole ``ask``,
the construction alone (the same colony without local search and merging), the local search
of those tours, the merge and the ``tell``. The local search's steps are counted per ant: the
vmapped search runs as many steps as its slowest ant, so the spread of steps says how much of
its time the other ants wait; ``--compact FIRST,BATCH`` times the same search with the ants
still searching after FIRST steps going on BATCH at a time (``two_opt(..., compact=)``), and
checks that it gives the same tours. ``--trace`` adds the device time of the search and of
the ask kernel by kernel (``kernel_trace.py``).

    python experiments/tsp_iteration_profile.py --size 5000 --warm 100 --repeats 5 \\
        --compact 6,192 --compact 8,384
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import sys
from pathlib import Path

import jax
import numpy as np
from common import timed, write_results
from kernel_trace import kernel_table
from tsp_large import random_instance

import eaco_jax as ea
from eaco_jax.ops import local_search
from eaco_jax.ops.tour_merge import merge_improvements
from eaco_jax.problems import load_tsplib
from eaco_jax.runs.tsp import LS_FOCUS_WIDTH, row_construction, row_pace, sparse_defaults
from eaco_jax.strategies.graph_eaco import GraphEACO

RESULTS = Path(__file__).resolve().parent / "results" / "tsp_large" / "iteration_profile.json"


def gpu_colony(n: int, ants: int, construction: str | None = None,
               max_new_edges: int | None = None, moves_plan: str | None = None,
               ls_loop: str | None = None, acceptance: str | None = None) -> GraphEACO:
    """The sparse GPU row's colony (``runs/tsp.py``) for ``n`` cities with ``ants`` ants; its
    construction and move acceptance by size unless given."""
    row = sparse_defaults("gpu")
    kind, edges = row_construction(row, n)
    pace = row_pace(row, n)
    if acceptance is None and pace is not None:
        acceptance = pace.ls_acceptance
    return GraphEACO(num_ants=ants, local_search="or-2opt", preset="mmas",
                     max_new_edges=max_new_edges or edges, construction=construction or kind,
                     ls_focus_width=LS_FOCUS_WIDTH, merge_ants=row.merge_ants or None,
                     **{k: v for k, v in (("moves_plan", moves_plan), ("ls_loop", ls_loop),
                                          ("ls_acceptance", acceptance)) if v is not None})


def profile(problem, colony: GraphEACO, warm: int, repeats: int,
            compacts: tuple[tuple[int, int], ...] = (), trace: bool = False) -> dict:
    """The timings and step counts of one size (see the module docstring)."""
    result = ea.minimize(problem, colony, seed=0, iterations=warm)
    state = result.state
    key = jax.random.PRNGKey(123)
    bare = dataclasses.replace(colony, local_search="none", merge_ants=None)
    ask = jax.jit(lambda k, s: colony.ask(k, s, problem))
    build = jax.jit(lambda k, s: bare.ask(k, s, problem)[0])
    tours0 = build(key, state)
    ref = state.best_solution
    focus = local_search.changed_cities(tours0, ref)
    dist = local_search.as_distances(problem.dist)

    @jax.jit
    def search(t, a):
        return local_search.two_opt(t, dist, problem.neighbors, None,
                                    moves_per_step=colony.ls_moves_per_step, or_opt=True,
                                    return_steps=True, active=a,
                                    focus_width=colony.ls_focus_width, loop=colony.ls_loop,
                                    acceptance=colony.ls_acceptance)

    searched, moves, steps = search(tours0, focus)
    merge = jax.jit(lambda t: merge_improvements(ref, t, problem.dist, colony.merge_ants))
    fitness = jax.jit(lambda t: problem.evaluate(t))
    lengths = fitness(searched)
    tell = jax.jit(lambda s, t, f: colony.tell(s, t, f, problem))
    out = {}
    for first, batch in compacts:  # the same search, the stragglers apart (same tours)
        compacted = jax.jit(lambda t, a, c=(first, batch): local_search.two_opt(
            t, dist, problem.neighbors, None, moves_per_step=colony.ls_moves_per_step,
            or_opt=True, active=a, focus_width=colony.ls_focus_width, compact=c,
            loop=colony.ls_loop, acceptance=colony.ls_acceptance))
        same = bool(np.array_equal(np.asarray(compacted(tours0, focus)), np.asarray(searched)))
        _, med = timed(lambda f=compacted: f(tours0, focus), repeats)
        out[f"local_search_compact_{first}_{batch}_seconds"] = med
        out[f"local_search_compact_{first}_{batch}_same_tours"] = same
    for name, fn in (("ask", lambda: ask(key, state)),
                     ("construction", lambda: build(key, state)),
                     ("local_search", lambda: search(tours0, focus)),
                     ("merge", lambda: merge(searched)),
                     ("evaluate", lambda: fitness(searched)),
                     ("tell", lambda: tell(state, searched, lengths))):
        _, med = timed(fn, repeats)
        out[f"{name}_seconds"] = med
    if trace:  # the device's kernels of the search and of the whole ask
        out["local_search_kernels"] = kernel_table(lambda: search(tours0, focus), repeats)
        out["ask_kernels"] = kernel_table(lambda: ask(key, state), repeats)
    steps = np.asarray(steps)
    moves = np.asarray(moves)
    ref_length = float(problem.exact_length(np.asarray(ref)))
    lens = np.asarray(lengths, dtype=np.float64)
    out.update({
        "warm_iterations": warm, "best_after_warm": ref_length,
        "steps_max": int(steps.max()), "steps_mean": float(steps.mean()),
        "steps_median": float(np.median(steps)), "steps_p90": float(np.percentile(steps, 90)),
        "moves_mean": float(moves.mean()), "moves_max": int(moves.max()),
        "changed_cities_mean": float(np.asarray(focus).sum(axis=1).mean()),
        "seconds_per_step": out["local_search_seconds"] / max(int(steps.max()), 1),
        "ants_shorter_than_best": int((lens < ref_length).sum()),
        "ants_equal_to_best": int((lens == ref_length).sum()),
    })
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, action="append", required=True, help="repeatable")
    ap.add_argument("--instance-seed", type=int, default=1)
    ap.add_argument("--ants", type=int, default=1536)
    ap.add_argument("--warm", type=int, default=100, help="iterations before the timings")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--construction", default=None,
                    help="moves / moves-new / moves-or3opt (default: the row's for the size)")
    ap.add_argument("--max-new-edges", type=int, default=None,
                    help="moves per ant (default: the row's for the size)")
    ap.add_argument("--compact", action="append", default=[],
                    help="FIRST_STEPS,BATCH: also time the search with the stragglers apart "
                         "(repeatable)")
    ap.add_argument("--moves-plan", default=None,
                    help="how the moves constructions hold a tour: arrays / pieces (the same "
                         "tours; GraphEACO.moves_plan; default: the library's)")
    ap.add_argument("--ls-loop", default=None,
                    help="how the focused search loops: ants / colony (the same tours; "
                         "GraphEACO.ls_loop; default: the library's)")
    ap.add_argument("--acceptance", default=None,
                    help="how a search step accepts its moves: rounds / unrolled (the same "
                         "tours; GraphEACO.ls_acceptance; default: the GPU row's by size, "
                         "else the library's)")
    ap.add_argument("--trace", action="store_true",
                    help="also the device time of the search and the ask, kernel by kernel")
    ap.add_argument("--work", type=Path, default=Path("/tmp/tsp_iteration_profile"))
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    rows = []
    for n in a.size:
        problem = load_tsplib(str(random_instance(a.work, n, a.instance_seed)), sparse=True)
        colony = gpu_colony(n, a.ants, a.construction, a.max_new_edges, a.moves_plan,
                            a.ls_loop, a.acceptance)
        row = {"n": n, "ants": a.ants, "instance_seed": a.instance_seed,
               "moves_plan": colony.moves_plan, "ls_loop": colony.ls_loop,
               "acceptance": colony.ls_acceptance,
               "construction": colony.construction, "max_new_edges": colony.max_new_edges,
               **profile(problem, colony, a.warm, a.repeats,
                         tuple(tuple(int(x) for x in c.split(",")) for c in a.compact), a.trace)}
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if not k.endswith("_kernels")}),
              flush=True)
    print(f"{'n':>7} {'ask':>8} {'build':>8} {'search':>8} {'merge':>8} {'tell':>8} "
          f"{'steps max/mean':>15}")
    for r in rows:
        print(f"{r['n']:>7} {r['ask_seconds']:8.4f} {r['construction_seconds']:8.4f} "
              f"{r['local_search_seconds']:8.4f} {r['merge_seconds']:8.4f} "
              f"{r['tell_seconds']:8.4f} {r['steps_max']:>6}/{r['steps_mean']:.1f}")
    write_results(a.out, rows, date=datetime.date.today().isoformat(),
                  command="tsp_iteration_profile.py " + " ".join(
                      argv if argv is not None else sys.argv[1:]),
                  seeds={"instance": a.instance_seed, "run": 0,
                         "role": "selection instance: chooses, reports nothing"})
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
