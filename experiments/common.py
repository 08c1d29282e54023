"""Helpers shared by the experiment scripts: instances, timed runs, cells, statistics, files.

Scripts run from the repository root as ``python experiments/NAME.py``; Python puts
``experiments/`` on the import path, so they ``import common`` with no path edits.

* Instances: :func:`find_instance` loads a bundled TSPLIB instance by name, or one from a data
  folder (``--data-dir``; default ``$EACO_TSPLIB_DIR``, ``out/tsplib`` and
  ``shared/data/tsplib`` beside the repository, ``/work/shared/data/tsplib``) with its optimum
  from that folder's ``optima.csv``.
* Timing: :func:`run_timed` runs ``eaco_jax.minimize(..., max_seconds=S)`` and records the
  best length after every chunk (compile time apart); :func:`timed` times a jitted call;
  :func:`run_cell` runs one experiment cell (all seeds vmapped, parameters unbatched).
* Statistics: :func:`bootstrap_ci`, :func:`t_ci`, :func:`paired_test` (Wilcoxon signed-rank,
  scipy), :func:`holm` (Holm-Bonferroni), :func:`summary`, :func:`success_performance`
  (CEC2006 SP) and :func:`stuck_fraction` (premature convergence).
* Files: :func:`device_info` names the device and versions for the JSON files, which
  :func:`write_results` writes.
* Processes: :func:`eaco_tsp` runs one fresh ``eaco tsp`` process and returns its record.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

REPO = Path(__file__).resolve().parent.parent


# --- instances, timed runs, result files ----------------------------------------------------
def data_dirs(extra: list[Path] | None = None) -> list[Path]:
    """Folders searched for ``NAME.tsp`` after the bundled instances, first match wins."""
    dirs = list(extra or [])
    if os.environ.get("EACO_TSPLIB_DIR"):
        dirs.append(Path(os.environ["EACO_TSPLIB_DIR"]))
    dirs += [REPO / "out" / "tsplib", REPO / "shared" / "data" / "tsplib",
             REPO.parent / "shared" / "data" / "tsplib", Path("/work/shared/data/tsplib")]
    return [d for d in dirs if d.is_dir()]


def find_instance(name: str, extra: list[Path] | None = None, neighbors: int | None = None):
    """A TSP by bundled name or from a data folder (optimum from its ``optima.csv``)."""
    from eaco_jax.problems import load_tsplib
    from eaco_jax.problems.tsp import DATA_DIR

    kw = {} if neighbors is None else {"neighbors": neighbors}
    if (DATA_DIR / f"{name}.tsp").is_file():
        return load_tsplib(name, **kw)
    for d in data_dirs(extra):
        path = d / f"{name}.tsp"
        if path.is_file():
            problem = load_tsplib(path, **kw)
            if problem.optimum is None and (d / "optima.csv").is_file():
                with open(d / "optima.csv", newline="") as fh:
                    optima = {r["name"]: float(r["optimal_tour_length"])
                              for r in csv.DictReader(fh)}
                if name in optima:
                    problem = problem.replace(optimum=optima[name])
            return problem
    raise FileNotFoundError(f"{name}.tsp is neither bundled nor in {data_dirs(extra)}; "
                            "pass --data-dir")


def device_info() -> dict:
    """Device kind, backend and versions, for results files."""
    dev = jax.devices()[0]
    return {"device": getattr(dev, "device_kind", str(dev)), "backend": jax.default_backend(),
            "device_count": jax.device_count(), "jax": jax.__version__,
            "host": platform.node(), "cpus": os.cpu_count(),
            "affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
            else None}


def write_results(path: Path, rows: list, **extra) -> None:
    """The benchmarks' JSON file: ``extra`` fields, device and versions, the command line's
    arguments and the rows."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({**extra, "info": device_info(), "argv": sys.argv[1:],
                                "rows": rows}, indent=1) + "\n")


def eaco_tsp(args: Sequence[Any], *, timeout: float | None = None, env: dict | None = None,
             cwd: str | Path | None = None) -> dict:
    """One fresh ``python -m eaco_jax tsp ARGS --out TMP`` process: ``record`` (its
    result.json without the tour; None when it failed), ``wall_seconds`` (the process, exit
    included), ``error`` (None, the end of its stderr, or the timeout) and ``argv`` (from
    ``tsp`` on)."""
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "eaco_jax", "tsp", *map(str, args), "--out", tmp]
        t0 = time.perf_counter()
        try:
            done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, env=env,
                                  cwd=cwd)
        except subprocess.TimeoutExpired:
            return {"record": None, "wall_seconds": timeout, "argv": argv[2:],
                    "error": f"killed after --process-timeout {timeout} s"}
        wall = time.perf_counter() - t0
        if done.returncode:
            return {"record": None, "wall_seconds": wall, "argv": argv[2:],
                    "error": done.stderr.strip()[-500:]}
        rec = json.loads((Path(tmp) / "result.json").read_text())
    rec.pop("tour", None)
    return {"record": rec, "wall_seconds": wall, "error": None, "argv": argv[2:]}


def enable_compile_cache(path: Path | None) -> None:
    """JAX's persistent compilation cache in ``path`` (a second run compiles nothing)."""
    if path is None:
        return
    path.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)


def run_timed(problem, strategy, seed: int, seconds: float, chunk: int,
              max_iterations: int = 10**7, params=None) -> dict:
    """One seeded run for ``seconds`` of search after compilation (``max_seconds``).

    Returns ``trace`` (``[seconds_after_compile, best_length, iterations]`` after every chunk,
    the driver's compute clock, compilation excluded), ``trace_from_call`` (the same with the
    wall time since ``minimize`` was called: initial state, compilation, host work between
    chunks, all included), ``compile_seconds`` (this call's; 0 when the compiled chunk came
    from this process's cache) and ``best``.
    """
    from eaco_jax import minimize

    trace: list[list] = []
    from_call: list[list] = []

    def record(state, progress) -> None:
        best = float(np.min(np.asarray(state.best_cost)))
        trace.append([round(progress.seconds, 4), best, int(progress.iterations)])
        from_call.append([round(time.perf_counter() - t_call, 4), best,
                          int(progress.iterations)])

    t_call = time.perf_counter()
    res = minimize(problem, strategy, seed=seed, iterations=max_iterations, chunk_size=chunk,
                   callback=record, max_seconds=seconds, params=params)
    chunk_s = float(np.median(np.diff([0.0] + [t for t, _, _ in trace]))) if trace else 0.0
    return {"seed": seed, "compile_seconds": float(res.compile_seconds),
            "chunk_seconds": chunk_s, "best": trace[-1][1] if trace else None,
            "iterations": trace[-1][2] if trace else 0, "stop_reason": res.stop_reason,
            "trace": trace, "trace_from_call": from_call}


def best_at(trace: list, t: float) -> float | None:
    """Best length reached by ``t`` seconds after compilation (None: no chunk ended by then)."""
    got = [b for s, b, _ in trace if s <= t]
    return min(got) if got else None


def timed(fn: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """(first-call seconds, median seconds of ``repeats`` further calls) of ``fn()``; the first
    call includes compilation, every call waits for its result (``block_until_ready``)."""
    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        walls.append(time.perf_counter() - t0)
    return first, statistics.median(walls)


# --- experiment cells (all seeds vmapped) -------------------------------------------------
_COMPILED: dict[Any, Any] = {}


def run_cell(problem: Any, strategy: Any, params: Any, seeds: list[int], iterations: int,
             chunk: int, stop: Any = None) -> dict[str, Any]:
    """One cell: all seeds vmapped, the params *unbatched* (so a switched-off rule is skipped
    by lax.cond, as in a single run, instead of both branches running under vmap as when
    settings are vmapped), compiled once per strategy and shapes.

    Returns the final state, the history (seeds, iterations), compute seconds per iteration
    (compilation excluded) and the iterations run (``stop(state)`` ends it early)."""
    from eaco_jax.driver.minimize import iteration_step

    problem = strategy.prepare(problem)
    keys = jnp.stack([jax.random.key(s) for s in seeds])
    state = jax.vmap(lambda k: strategy.init(k, problem, params))(keys)
    params = state.params  # as the strategy cast them; strip the batch axis
    params = jax.tree.map(lambda x: x[0], params)
    state = state.replace(params=None)

    def one(prob, prm, s):
        def body(c, _):
            c, metrics = iteration_step(strategy, prob, c.replace(params=prm))
            return c.replace(params=None), metrics

        return jax.lax.scan(body, s, None, length=chunk)

    key = (strategy, chunk, _signature(problem), _signature(state), _signature(params))
    if key not in _COMPILED:
        fn = jax.jit(jax.vmap(one, in_axes=(None, None, 0)))
        _COMPILED[key] = fn.lower(problem, params, state).compile()
    fn = _COMPILED[key]
    done, seconds, hist = 0, 0.0, []
    while done < iterations:
        t0 = time.perf_counter()
        state, h = fn(problem, params, state)
        jax.block_until_ready(state)
        seconds += time.perf_counter() - t0
        hist.append({k: np.asarray(v) for k, v in h.items()})
        done += chunk
        if stop is not None and stop(state):
            break
    metrics = {k: np.concatenate([h[k] for h in hist], axis=1)[:, :iterations]
               for k in hist[0]}
    return dict(state=state.replace(params=params), history=metrics["best_cost"],
                metrics=metrics, iterations=min(done, iterations),
                seconds_per_iteration=seconds / max(done, 1))


def _signature(tree: Any) -> tuple:
    """Tree structure (static metadata included) and leaf shapes / dtypes."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x)))) for x in leaves)


def divisor_chunk(iterations: int, chunks: int) -> int:
    """A chunk length that divides ``iterations``, about iterations / chunks."""
    want = max(1, iterations // chunks)
    return max(c for c in range(1, want + 1) if iterations % c == 0)


# --- statistics -----------------------------------------------------------------------------
def bootstrap_ci(x: Sequence[float], level: float = 0.95, resamples: int = 10_000,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of the mean of ``x`` (finite values only)."""
    a = np.asarray(x, np.float64)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return (math.nan, math.nan)
    if a.size == 1 or np.all(a == a[0]):
        return (float(a[0]), float(a[0])) if a.size else (math.nan, math.nan)
    rng = np.random.default_rng(seed)
    means = a[rng.integers(0, a.size, (resamples, a.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def t_ci(x: Sequence[float], level: float = 0.95) -> tuple[float, float]:
    """Student-t CI of the mean."""
    from scipy import stats

    a = np.asarray(x, np.float64)
    a = a[np.isfinite(a)]
    if a.size < 2:
        return (math.nan, math.nan)
    half = stats.t.ppf((1 + level) / 2, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size)
    return float(a.mean() - half), float(a.mean() + half)


def paired_test(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided Wilcoxon signed-rank p-value for seed-paired samples ``a`` and ``b``.

    Infinite values (a run that never reached a feasible point / the target) are replaced by
    a value above every finite one in the pair, so they rank as the worst; all-zero
    differences give p = 1.
    """
    from scipy import stats

    x, y = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if x.shape != y.shape:
        raise ValueError(f"paired samples differ in length: {x.shape} vs {y.shape}")
    both = np.concatenate([x, y])
    finite = both[np.isfinite(both)]
    worst = (finite.max() + 1.0 + abs(finite.max())) if finite.size else 1.0
    x, y = np.where(np.isfinite(x), x, worst), np.where(np.isfinite(y), y, worst)
    d = x - y
    if np.all(d == 0):
        return 1.0
    return float(stats.wilcoxon(x, y, zero_method="wilcox").pvalue)


def holm(p: Sequence[float]) -> list[float]:
    """Holm-Bonferroni adjusted p-values (same order as ``p``)."""
    p = np.asarray(p, np.float64)
    order = np.argsort(p)
    m = p.size
    adjusted = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        adjusted[i] = running
    return adjusted.tolist()


def summary(x: Sequence[float]) -> dict[str, float]:
    """mean, bootstrap 95 % CI, median, min, max of the finite values, and how many are not."""
    a = np.asarray(x, np.float64)
    f = a[np.isfinite(a)]
    lo, hi = bootstrap_ci(f)
    nan = math.nan
    return {"mean": float(f.mean()) if f.size else nan, "ci_low": lo, "ci_high": hi,
            "median": float(np.median(f)) if f.size else nan,
            "min": float(f.min()) if f.size else nan, "max": float(f.max()) if f.size else nan,
            "n": int(a.size), "non_finite": int(a.size - f.size)}


def success_performance(evals_to_target: Sequence[float]) -> float | None:
    """CEC2006 SP: mean evaluations of the successful runs x runs / successes (None if none).
    Unsuccessful runs are negative or non-finite entries."""
    e = np.asarray(evals_to_target, np.float64)
    ok = np.isfinite(e) & (e >= 0)
    if not ok.any():
        return None
    return float(e[ok].mean() * e.size / ok.sum())


def stuck_fraction(final: Sequence[float], target: float) -> float:
    """Premature-convergence estimate: the fraction of runs above ``target`` at the budget."""
    f = np.asarray(final, np.float64)
    return float(np.mean(~(f <= target)))
