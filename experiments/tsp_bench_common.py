"""Shared pieces of the TSP benchmarks: finding instances, timed runs through the public API.

* :func:`find_instance` loads a bundled TSPLIB instance by name, or one from a data folder
  (``--data-dir``; default ``$EACO_TSPLIB_DIR``, ``out/tsplib`` and ``shared/data/tsplib``
  beside the repository, ``/work/shared/data/tsplib``) with its optimum from that folder's
  ``optima.csv``.
* :func:`run_timed` runs ``eaco_jax.minimize(..., max_seconds=S)`` and records the best
  length after every chunk (a ``callback``). Compile time is reported apart.
* :func:`device_info` names the device and versions for the JSON files, which
  :func:`write_results` writes.
"""

from __future__ import annotations

import csv
import os
import platform
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


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
    import jax

    dev = jax.devices()[0]
    return {"device": getattr(dev, "device_kind", str(dev)), "backend": jax.default_backend(),
            "device_count": jax.device_count(), "jax": jax.__version__,
            "host": platform.node(), "cpus": os.cpu_count(),
            "affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
            else None}


def write_results(path: Path, rows: list, **extra) -> None:
    """The benchmarks' JSON file: ``extra`` fields, device and versions, the command line's
    arguments and the rows."""
    import json
    import sys

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({**extra, "info": device_info(), "argv": sys.argv[1:],
                                "rows": rows}, indent=1) + "\n")


def enable_compile_cache(path: Path | None) -> None:
    """JAX's persistent compilation cache in ``path`` (a second run compiles nothing)."""
    if path is None:
        return
    import jax

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
    import numpy as np

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
