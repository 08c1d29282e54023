"""Where a fresh process's first TSP chunk spends its time, cold and with warm caches.

``--what phases`` takes the chunk apart by hand: jit (trace, lower, compile) against the chunk
exported with ``jax.export`` (deserialize, lower, compile), the measurement behind
``eaco_jax/driver/program_cache.py``, and against the compiled executable itself serialised
(``jax.experimental.serialize_executable``: read, deserialise and load; no lowering, no
lookup in JAX's cache). ``--what driver`` (default) times what a user sees:
``minimize`` in fresh processes with JAX's persistent cache on, the program cache off and on
(wall seconds from the call to the first chunk's result, the part of them spent before the
first chunk ran, and the compile seconds ``minimize`` reports).
One process per row; the first of each mode starts from empty caches.

    python experiments/startup_phases.py --instance pcb442 --ants 1024 --local-search or-2opt
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r'''
import json, sys, time
t00 = time.perf_counter()
import jax, jax.numpy as jnp
from jax import export
cache, mode, inst, ants, ls, blob_path = sys.argv[1:7]
jax.config.update("jax_compilation_cache_dir", cache)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
from eaco_jax.driver import minimize as M
from eaco_jax.problems.tsp import load_tsplib
from eaco_jax.strategies.graph_eaco import GraphEACO
T = {}
t = time.perf_counter(); T["import"] = t - t00
prob = load_tsplib(inst)
strat = GraphEACO(num_ants=int(ants), local_search=ls)
state = jax.block_until_ready(strat.init(jax.random.key(0), prob))
t1 = time.perf_counter(); T["problem_init"] = t1 - t
args = (prob, state, jnp.int32(5))
leaves, in_def = jax.tree.flatten(args)
fn = M.make_chunk_fn(strat, 5, False, False)
best_of = lambda out: out[0].best_cost
box = {}
def flat(*xs):  # the chunk on flat leaves: its trees need no serialising
    out = fn(*jax.tree.unflatten(in_def, xs))
    paths = [jax.tree_util.keystr(p) for p, _ in jax.tree_util.tree_flatten_with_path(out)[0]]
    box["meta"] = {"outputs": len(paths), "best": paths.index("[0].best_cost")}
    return jax.tree.leaves(out)
def flat_run(c, meta):  # a compiled flat chunk: run it, read the best cost by its index
    global best_of
    best_of = lambda out: out[meta["best"]]
    return lambda: c(*leaves)
if mode == "jit":
    tr = fn.trace(*args); t2 = time.perf_counter(); T["trace"] = t2 - t1
    lo = tr.lower(); t3 = time.perf_counter(); T["lower"] = t3 - t2
    c = lo.compile(); t4 = time.perf_counter(); T["compile"] = t4 - t3
    run = lambda: c(*args)
elif mode == "executable":
    import os
    from jax.experimental import serialize_executable as se
    if not os.path.exists(blob_path):
        c = jax.jit(flat).lower(*leaves).compile()
        payload, _, _ = se.serialize(c)
        open(blob_path, "wb").write(payload)
        open(blob_path + ".json", "w").write(json.dumps(box["meta"]))
        T["compile_and_serialize"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    payload = open(blob_path, "rb").read()
    meta = json.loads(open(blob_path + ".json").read())
    i_t = jax.tree.structure((tuple(leaves), {}))
    o_t = jax.tree.structure([0] * meta["outputs"])
    t3 = time.perf_counter(); T["deserialize"] = t3 - t2
    c = se.deserialize_and_load(payload, i_t, o_t)
    t4 = time.perf_counter(); T["lower_compile"] = t4 - t3
    run = flat_run(c, meta)
else:
    import os
    if not os.path.exists(blob_path):
        checks = [export.DisabledSafetyCheck.custom_call(t)
                  for t in ("triton_kernel_call", "__gpu$xla.gpu.triton")]
        exp = export.export(jax.jit(flat), disabled_checks=checks)(*leaves)
        open(blob_path, "wb").write(exp.serialize())
        open(blob_path + ".json", "w").write(json.dumps(box["meta"]))
        T["export"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    exp = export.deserialize(bytearray(open(blob_path, "rb").read()))
    meta = json.loads(open(blob_path + ".json").read())
    t3 = time.perf_counter(); T["deserialize"] = t3 - t2
    c = jax.jit(exp.call).lower(*leaves).compile()
    t4 = time.perf_counter(); T["lower_compile"] = t4 - t3
    run = flat_run(c, meta)
out = jax.block_until_ready(run()); t5 = time.perf_counter(); T["first_chunk"] = t5 - t4
jax.block_until_ready(run()); T["second_chunk"] = time.perf_counter() - t5
T["best"] = float(best_of(out))
T["total_to_first_result"] = time.perf_counter() - t00 - T["second_chunk"]
print("PHASES " + json.dumps(T))
'''

DRIVER = r'''
import json, sys, time
t00 = time.perf_counter()
import jax
cache, mode, inst, ants, ls = sys.argv[1:6]
jax.config.update("jax_compilation_cache_dir", cache)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
import eaco_jax as ea
from eaco_jax.driver import program_cache
from eaco_jax.problems.tsp import load_tsplib
from eaco_jax.strategies.graph_eaco import GraphEACO
if mode == "program_cache_off":
    program_cache.set_folder(None)
T = {}
prob = load_tsplib(inst)
jax.block_until_ready(prob.dist)
t1 = time.perf_counter(); T["import_and_problem"] = t1 - t00
seen = []
res = ea.minimize(prob, GraphEACO(num_ants=int(ants), local_search=ls), seed=0, iterations=10,
                  chunk_size=5,
                  callback=lambda s, p: seen.append((time.perf_counter() - t1, p.seconds)))
T["call_to_first_result"] = seen[0][0]
T["before_first_chunk"] = seen[0][0] - seen[0][1]  # initial state, compilation, host work
T["compile_seconds"] = res.compile_seconds
T["chunk_seconds"] = seen[1][1] - seen[0][1]
T["best"] = float(res.best_cost)
print("PHASES " + json.dumps(T))
'''


def child(cache: str, mode: str, args, blob: str) -> dict:
    code, extra = (CHILD, [blob]) if args.what == "phases" else (DRIVER, [])
    out = subprocess.run([sys.executable, "-c", code, cache, mode, args.instance,
                          str(args.ants), args.local_search, *extra],
                         capture_output=True, text=True, env=dict(os.environ))
    for line in out.stdout.splitlines():
        if line.startswith("PHASES "):
            return json.loads(line[7:])
    raise RuntimeError(out.stderr[-3000:])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instance", default="pcb442")
    ap.add_argument("--ants", type=int, default=1024)
    ap.add_argument("--local-search", default="or-2opt")
    ap.add_argument("--warm", type=int, default=2, help="warm processes per mode")
    ap.add_argument("--what", choices=["driver", "phases"], default="driver")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    from common import write_results

    rows = []
    modes = (("jit", "export", "executable") if args.what == "phases"
             else ("program_cache_off", "program_cache_on"))
    for mode in modes:
        with tempfile.TemporaryDirectory() as tmp:  # each mode starts from empty caches
            cache, blob = str(Path(tmp) / "cache"), str(Path(tmp) / "chunk.bin")
            for i in range(1 + args.warm):
                r = {"mode": mode, "process": i, **child(cache, mode, args, blob)}
                rows.append(r)
                print(json.dumps({k: round(v, 3) if isinstance(v, float) else v
                                  for k, v in r.items()}), flush=True)
    if args.out:
        write_results(args.out, rows)


if __name__ == "__main__":
    main()
