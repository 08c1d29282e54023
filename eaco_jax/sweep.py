"""Hyper-parameter sweeps: grid, listed or random settings x seeds, batched where possible.

A sweep is a set of *cells* (one setting of the swept keys each) times a list of seeds. Swept
keys that are fields of the strategy's Params pytree are *traced*: cells that differ only in
them share one compiled program, so they run as ONE vmapped, jitted call over stacked params x
seeds (:func:`eaco_jax.minimize.minimize_batch`). Any other key is a *static* argument of the
run command (number of ants, problem, budget, ...); cells with different static arguments run
one group after another.

Each finished cell is written to ``OUT/cells/<cell id>.json`` as soon as its group ends, so an
interrupted sweep started again skips finished cells. The whole table lands in
``OUT/table.csv`` and ``OUT/table.json`` (one row per cell x seed) with a per-cell summary
(``OUT/summary.json``) and a plot (``OUT/summary.png``).

The spec (a dict, usually from YAML, see :mod:`eaco_jax.cli.sweep` for the file format) names
a ``command`` whose *builder* turns the command's arguments into a :class:`Setup` (with the
command's defaults); builders for ``constrained``, ``tsp`` and ``gait`` live here, a custom one
is named as ``builder: "module:function"``.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import importlib
import itertools
import json
import math
import random
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np

from eaco_jax.driver.minimize import Result, minimize_batch


@dataclasses.dataclass
class Setup:
    """What a builder makes of a command's arguments.

    ``metrics(result, row)`` adds columns for one row of a batched result (feasibility, gap,
    ``success`` - counted in the summary). ``context()``, if given, is entered around building
    and running (e.g. :func:`eaco_jax.problems.float64` for the constrained command).
    """

    problem: Any
    strategy: Any
    params: Any
    iterations: int | None = None
    max_evaluations: int | None = None
    chunk_size: int | None = None
    metrics: Callable[[Result, int], dict[str, Any]] | None = None
    context: Callable[[], AbstractContextManager] | None = None


@dataclasses.dataclass
class Cell:
    """One setting of the swept keys: static command arguments and traced params overrides."""

    id: str
    values: dict[str, Any]
    args: dict[str, Any]
    params: dict[str, Any]

    def group_key(self) -> str:
        return json.dumps(self.args, sort_keys=True, default=str)


# --------------------------------------------------------------------------- builders
def _build_constrained(args: dict[str, Any]) -> Setup:
    """``constrained`` command: a CEC2006 problem (or test function), continuous EACO, float64.

    Arguments: ``problem`` (g01..g13, G1..G4, sphere, ...), ``method`` (constraint handling),
    ``max_evaluations`` or ``iterations``, ``chunk_size`` (default 50 as the command), and any
    static field of :class:`~eaco_jax.strategies.continuous_eaco.ContinuousEACO`.
    """
    from eaco_jax.cli.constrained import load_problem
    from eaco_jax.problems.constrained import float64
    from eaco_jax.strategies.continuous_eaco import TARGET_TOLERANCE, ContinuousEACO

    args = dict(args)
    name = str(args.pop("problem", "g01"))
    if "method" in args:
        args["constraint_method"] = args.pop("method")
    budget = _pop_budget(args)
    chunk = int(args.pop("chunk_size", 50))
    if "ants" in args:
        args["num_ants"] = int(args.pop("ants"))
    with float64():
        problem = load_problem(name)
    strategy = ContinuousEACO(**args)
    f_star = problem.f_star

    def metrics(result: Result, row: int) -> dict[str, Any]:
        f = float(np.asarray(result.f)[row])
        v = float(np.asarray(result.violation)[row])
        out: dict[str, Any] = {"f": f, "violation": v, "feasible": bool(v <= 0.0)}
        if f_star is not None:
            out["error"] = f - float(f_star)
            out["success"] = bool(v <= 0.0 and f - float(f_star) <= TARGET_TOLERANCE)
        return out

    return Setup(problem, strategy, strategy.default_params(problem), chunk_size=chunk,
                 metrics=metrics, context=float64, **budget)


def _pop_budget(args: dict[str, Any]) -> dict[str, int]:
    return {k: int(args.pop(k)) for k in ("iterations", "max_evaluations") if k in args}


def _build_tsp(args: dict[str, Any]) -> Setup:
    """``tsp`` command: a TSPLIB instance with the graph EACO colony.

    Arguments as ``eaco tsp``: ``instance``, ``ants``, ``iterations``, ``local_search`` (bool),
    plus any static field of :class:`~eaco_jax.strategies.graph_eaco.GraphEACO`.
    """
    from eaco_jax.cli.tsp import DEFAULT_ITERATIONS
    from eaco_jax.problems.tsp import load_tsplib
    from eaco_jax.strategies.graph_eaco import GraphEACO

    args = dict(args)
    problem = load_tsplib(str(args.pop("instance", args.pop("problem", "eil51"))))
    budget = _pop_budget(args) or {"iterations": DEFAULT_ITERATIONS}
    chunk = args.pop("chunk_size", None)
    if "ants" in args:
        args["num_ants"] = int(args.pop("ants"))
    if isinstance(args.get("local_search"), bool):
        args["local_search"] = "2opt" if args["local_search"] else "none"
    strategy = GraphEACO(**args)
    optimum = problem.optimum

    def metrics(result: Result, row: int) -> dict[str, Any]:
        if optimum is None:
            return {}
        cost = float(np.asarray(result.best_cost)[row])
        return {"gap_percent": 100.0 * (cost / float(optimum) - 1.0),
                "success": bool(cost <= float(optimum))}

    return Setup(problem, strategy, strategy.default_params(problem), chunk_size=chunk,
                 metrics=metrics, **budget)


def _build_gait(args: dict[str, Any]) -> Setup:
    """``gait`` command: walk-engine parameters of a robot with continuous EACO (no gradients).

    Arguments as ``eaco gait``: ``robot``, ``backend``, ``ants``, ``iterations``, ``horizon``,
    ``direction``, ``slope``. The cost is minus the distance walked (``fitness`` column).
    """
    from eaco_jax.cli.gait import DEFAULT_ANTS, DEFAULT_HORIZON, DEFAULT_ITERATIONS
    from eaco_jax.problems.gait import make_gait_problem
    from eaco_jax.strategies.continuous_eaco import ContinuousEACO

    args = dict(args)
    gait = make_gait_problem(
        str(args.pop("robot", "nao")), backend=str(args.pop("backend", "auto")),
        horizon=float(args.pop("horizon", DEFAULT_HORIZON)),
        direction_deg=float(args.pop("direction", 0.0)),
        slope_deg=float(args.pop("slope", 0.0)),
    )
    budget = _pop_budget(args) or {"iterations": DEFAULT_ITERATIONS}
    ants = int(args.pop("ants", args.pop("num_ants", DEFAULT_ANTS)))
    if args:
        raise ValueError(f"gait sweeps do not take {sorted(args)}")
    strategy = ContinuousEACO(num_ants=ants, archive_size=max(2, (3 * ants) // 2),
                              refine_ants=0, repair_steps=0)
    problem = gait.as_constrained()

    def metrics(result: Result, row: int) -> dict[str, Any]:
        return {"fitness": -float(np.asarray(result.best_cost)[row])}

    return Setup(problem, strategy, strategy.default_params(problem), metrics=metrics, **budget)


BUILDERS: dict[str, Callable[[dict[str, Any]], Setup]] = {
    "constrained": _build_constrained,
    "tsp": _build_tsp,
    "gait": _build_gait,
}


def get_builder(spec: dict[str, Any]) -> Callable[[dict[str, Any]], Setup]:
    """The spec's ``builder: "module:function"``, else the builder of its ``command``."""
    name = spec.get("builder")
    if name:
        module, _, attr = str(name).partition(":")
        if not attr:
            raise ValueError(f"builder must look like 'package.module:function', got {name!r}")
        try:
            return getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as err:
            raise ValueError(f"cannot import sweep builder {name!r}: {err}") from None
    command = spec.get("command")
    if command not in BUILDERS:
        raise ValueError(
            f"sweep command {command!r} has no builder (known: {', '.join(sorted(BUILDERS))}); "
            "name one with builder: 'module:function'"
        )
    return BUILDERS[command]


# --------------------------------------------------------------------------- spec -> cells
SPEC_KEYS = {"command", "builder", "args", "seeds", "grid", "cells", "random",
             "checkpoint_every", "name"}


def validate_spec(spec: Any) -> dict[str, Any]:
    """Check the spec's top-level shape; one clear error for anything malformed."""
    if not isinstance(spec, dict):
        raise ValueError("a sweep spec must be a mapping (YAML dict) at the top level")
    unknown = set(spec) - SPEC_KEYS
    if unknown:
        raise ValueError(f"unknown sweep keys {sorted(unknown)}; allowed: {sorted(SPEC_KEYS)}")
    if "command" not in spec and "builder" not in spec:
        raise ValueError("a sweep spec needs 'command' (tsp, constrained, ...) or 'builder'")
    if "random" in spec and ("grid" in spec or "cells" in spec):
        raise ValueError("use either 'random' or 'grid'/'cells' in one sweep, not both")
    for key in ("args", "grid", "random"):
        if key in spec and not isinstance(spec[key], dict):
            raise ValueError(f"sweep '{key}' must be a mapping")
    if "cells" in spec and not (isinstance(spec["cells"], list)
                                and all(isinstance(c, dict) for c in spec["cells"])):
        raise ValueError("sweep 'cells' must be a list of mappings")
    for name, values in (spec.get("grid") or {}).items():
        if not isinstance(values, list) or not values:
            raise ValueError(f"grid entry {name!r} must be a non-empty list")
    seeds_of(spec)
    return spec


def seeds_of(spec: dict[str, Any]) -> list[int]:
    """``seeds: 10`` means 0..9; a list is taken as it is."""
    seeds = spec.get("seeds", 1)
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            raise ValueError(f"seeds must be >= 1, got {seeds}")
        return list(range(seeds))
    if isinstance(seeds, list) and seeds and all(isinstance(s, int) for s in seeds):
        return [int(s) for s in seeds]
    raise ValueError(f"seeds must be a positive int or a list of ints, got {seeds!r}")


def _settings(spec: dict[str, Any]) -> list[dict[str, Any]]:
    if "random" in spec:
        return _random_settings(spec["random"])
    base = spec.get("cells") or [{}]
    grid = spec.get("grid") or {}
    names = list(grid)
    product = [dict(zip(names, combo, strict=True))
               for combo in itertools.product(*(grid[n] for n in names))]
    return [{**cell, **combo} for cell in base for combo in product]


def _random_settings(rnd: dict[str, Any]) -> list[dict[str, Any]]:
    n, space = rnd.get("n"), rnd.get("space")
    if not isinstance(n, int) or n < 1 or not isinstance(space, dict) or not space:
        raise ValueError("random sweeps need 'n' (>= 1) and a 'space' mapping")
    rng = random.Random(int(rnd.get("seed", 0)))
    out = []
    for _ in range(n):
        cell = {}
        for name, dist in space.items():
            if isinstance(dist, list) and len(dist) == 2:
                dist = {"low": dist[0], "high": dist[1]}
            if isinstance(dist, dict) and "choice" in dist:
                cell[name] = rng.choice(list(dist["choice"]))
            elif isinstance(dist, dict) and "low" in dist and "high" in dist:
                lo, hi = float(dist["low"]), float(dist["high"])
                if not lo < hi:
                    raise ValueError(f"random space {name!r}: low must be < high")
                if dist.get("log"):
                    if lo <= 0:
                        raise ValueError(f"random space {name!r}: log range needs low > 0")
                    cell[name] = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
                else:
                    cell[name] = rng.uniform(lo, hi)
            else:
                raise ValueError(
                    f"random space {name!r} must be [low, high], {{low, high, log}} or "
                    "{choice: [...]}"
                )
        out.append(cell)
    return out


def param_fields(params: Any) -> set[str]:
    """Names of the traced hyper-parameters (fields of the Params dataclass)."""
    if not dataclasses.is_dataclass(params):
        return set()
    return {f.name for f in dataclasses.fields(params)}


def expand(spec: dict[str, Any], base_setup: Setup) -> list[Cell]:
    """The sweep's cells; swept keys that are Params fields go to ``params``, others to args."""
    traced = param_fields(base_setup.params)
    base_args = dict(spec.get("args") or {})
    seeds = seeds_of(spec)
    cells = []
    for index, values in enumerate(_settings(spec)):
        params = {k: v for k, v in values.items() if k in traced}
        args = {**base_args, **{k: v for k, v in values.items() if k not in traced}}
        ident = json.dumps([values, args, seeds, spec.get("command"), spec.get("builder")],
                           sort_keys=True, default=str)
        digest = hashlib.sha256(ident.encode()).hexdigest()[:8]
        cells.append(Cell(f"c{index:03d}-{digest}", values, args, params))
    return cells


def groups_of(cells: list[Cell]) -> list[list[Cell]]:
    """Cells sharing all static arguments, in first-seen order (each group = one call)."""
    groups: dict[str, list[Cell]] = {}
    for cell in cells:
        groups.setdefault(cell.group_key(), []).append(cell)
    return list(groups.values())


def with_params(base: Any, overrides: dict[str, Any]) -> Any:
    """``base`` Params with ``overrides``; every field becomes an array of its default's dtype.

    Python-scalar defaults take JAX's default dtype (float32, or float64 inside
    :func:`eaco_jax.problems.float64`), so all cells stack into one batch.
    """
    changes = {}
    for f in dataclasses.fields(base):
        value = getattr(base, f.name)
        dtype = jnp.asarray(value).dtype
        if f.name in overrides:
            value = overrides[f.name]
            if not np.isfinite(np.asarray(value, dtype=np.float64)).all():
                raise ValueError(f"swept value {f.name}={value!r} is not finite")
        changes[f.name] = jnp.asarray(value, dtype=dtype)
    return base.replace(**changes)


# --------------------------------------------------------------------------- running
def run_group(
    builder: Callable[[dict[str, Any]], Setup],
    cells: list[Cell],
    seeds: list[int],
    *,
    progress: bool = False,
    checkpoint_dir: Path | None = None,
    checkpoint_every: int | None = None,
) -> dict[str, dict[str, Any]]:
    """Run cells that share static arguments as one vmapped call; cell id -> cell record."""
    setup = builder(dict(cells[0].args))
    if setup.context is not None:
        with setup.context():
            return _run_group(builder(dict(cells[0].args)), cells, seeds, progress,
                              checkpoint_dir, checkpoint_every)
    return _run_group(setup, cells, seeds, progress, checkpoint_dir, checkpoint_every)


def _run_group(
    setup: Setup, cells: list[Cell], seeds: list[int], progress: bool,
    checkpoint_dir: Path | None, checkpoint_every: int | None,
) -> dict[str, dict[str, Any]]:
    params = [with_params(setup.params, c.params) for c in cells]
    t0 = time.perf_counter()
    result = minimize_batch(
        setup.problem, setup.strategy, params, seed=seeds, iterations=setup.iterations,
        max_evaluations=setup.max_evaluations, chunk_size=setup.chunk_size, progress=progress,
        checkpoint_dir=checkpoint_dir,
        checkpoint_every=checkpoint_every if checkpoint_dir is not None else None,
    )
    seconds = time.perf_counter() - t0
    records = {}
    for i, cell in enumerate(cells):
        rows = []
        for j, seed in enumerate(seeds):
            r = i * len(seeds) + j
            row = {
                "cell": cell.id, **cell.values, "seed": seed,
                "best_cost": float(np.asarray(result.best_cost)[r]),
                "iterations": int(result.iterations),
                "evaluations": int(np.asarray(result.evaluations)[r]),
            }
            if setup.metrics is not None:
                row.update(setup.metrics(result, r))
            rows.append(row)
        records[cell.id] = {
            "cell": cell.id, "values": cell.values, "args": cell.args, "seeds": seeds,
            "group_cells": len(cells), "group_seconds": seconds,
            "compile_seconds": result.compile_seconds, "rows": rows,
        }
    return records


def cell_path(out: Path, cell: Cell) -> Path:
    return out / "cells" / f"{cell.id}.json"


def write_cell(out: Path, record: dict[str, Any]) -> None:
    """Atomically write one finished cell (tmp file + rename)."""
    from eaco_jax.cli.common import to_jsonable

    path = out / "cells" / f"{record['cell']}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(to_jsonable(record), indent=1) + "\n")
    tmp.replace(path)


def read_cell(out: Path, cell: Cell) -> dict[str, Any] | None:
    path = cell_path(out, cell)
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
    except json.JSONDecodeError:
        return None  # a half-written cell file cannot exist (rename), but never trust it
    return record if record.get("cell") == cell.id else None


def plan(spec: dict[str, Any]) -> tuple[Callable[[dict[str, Any]], Setup], list[Cell]]:
    """Validate the spec, build the base setup once and expand the cells."""
    spec = validate_spec(spec)
    builder = get_builder(spec)
    base = builder(dict(spec.get("args") or {}))
    cells = expand(spec, base)
    return builder, cells


def run_sweep(
    spec: dict[str, Any],
    out: str | Path,
    *,
    backend: str = "local",
    progress: bool = False,
    ray_options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Run (or finish) a sweep into folder ``out``; returns the summary record."""
    out = Path(out)
    builder, cells = plan(spec)
    seeds = seeds_of(spec)
    every = spec.get("checkpoint_every")
    todo = [c for c in cells if read_cell(out, c) is None]
    out.mkdir(parents=True, exist_ok=True)
    (out / "spec.json").write_text(json.dumps(spec, indent=1, default=str) + "\n")
    t0 = time.perf_counter()
    if backend == "local":
        groups = groups_of(todo)
        bar = _bar(progress, len(cells), len(cells) - len(todo))
        try:
            for group in groups:
                ck = None
                if every is not None:
                    tag = hashlib.sha256("".join(c.id for c in group).encode()).hexdigest()[:10]
                    ck = out / "checkpoints" / f"group-{tag}"
                for record in run_group(builder, group, seeds, progress=progress,
                                        checkpoint_dir=ck, checkpoint_every=every).values():
                    write_cell(out, record)
                if bar is not None:
                    bar.update(len(group))
        finally:
            if bar is not None:
                bar.close()
    elif backend == "ray":
        from eaco_jax.ray_backend import run_cells_on_ray

        run_cells_on_ray(spec, todo, seeds, out, progress=progress, **(ray_options or {}))
    else:
        raise ValueError(f"unknown sweep backend {backend!r}; use 'local' or 'ray'")
    wall = time.perf_counter() - t0
    records = [read_cell(out, c) for c in cells]
    missing = [c.id for c, r in zip(cells, records, strict=True) if r is None]
    if missing:
        raise RuntimeError(f"sweep cells {missing} did not finish; run the sweep again")
    return write_tables(out, spec, cells, records, wall, ran=len(todo))


def _bar(progress: bool, total: int, initial: int):
    if not progress:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc="sweep", unit="cell")


# --------------------------------------------------------------------------- tables
def summarise(record: dict[str, Any]) -> dict[str, Any]:
    costs = np.array([r["best_cost"] for r in record["rows"]], dtype=np.float64)
    finite = costs[np.isfinite(costs)]
    out = {
        "cell": record["cell"], **record["values"], "runs": len(costs),
        "best": float(finite.min()) if finite.size else None,
        "mean": float(finite.mean()) if finite.size else None,
        "std": float(finite.std()) if finite.size else None,
        "median": float(np.median(finite)) if finite.size else None,
    }
    if all("success" in r for r in record["rows"]):
        out["success_rate"] = float(np.mean([bool(r["success"]) for r in record["rows"]]))
    if all("feasible" in r for r in record["rows"]):
        out["feasible_rate"] = float(np.mean([bool(r["feasible"]) for r in record["rows"]]))
    return out


def write_tables(
    out: Path, spec: dict[str, Any], cells: list[Cell], records: list[dict[str, Any]],
    wall: float, ran: int,
) -> dict[str, Any]:
    """table.csv / table.json (cell x seed rows), summary.json and summary.png."""
    from eaco_jax.cli.common import to_jsonable, write_json

    rows = [row for rec in records for row in rec["rows"]]
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    with (out / "table.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    write_json(out / "table.json", {"columns": columns, "rows": rows})
    summary = [summarise(r) for r in records]
    record = {
        "name": spec.get("name") or spec.get("command") or spec.get("builder"),
        "out": str(out), "cells": len(cells), "seeds": seeds_of(spec), "runs": len(rows),
        "cells_run_now": ran, "wall_seconds": wall,
        "groups": len(groups_of(cells)),
        "table_csv": str(out / "table.csv"), "table_json": str(out / "table.json"),
        "plot": str(out / "summary.png"), "summary": summary,
    }
    write_json(out / "summary.json", to_jsonable(record))
    plot_summary(out / "summary.png", records, record["name"])
    return record


def plot_summary(path: Path, records: list[dict[str, Any]], title: Any) -> None:
    """Box plot of every cell's best cost over seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = [[r["best_cost"] for r in rec["rows"] if math.isfinite(r["best_cost"])] or [np.nan]
            for rec in records]
    labels = [", ".join(f"{k}={_fmt(v)}" for k, v in rec["values"].items()) or rec["cell"]
              for rec in records]
    fig, ax = plt.subplots(figsize=(max(5.0, 0.6 * len(records) + 2), 4.5))
    ax.boxplot(data)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("best cost over seeds")
    ax.set_title(f"sweep {title}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _fmt(v: Any) -> str:
    return f"{v:.3g}" if isinstance(v, float) else str(v)
