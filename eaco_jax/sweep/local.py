"""Running cells on this machine: each group of cells as one vmapped call; each finished cell
is written to ``OUT/cells/<cell id>.json`` as soon as its group ends, so an interrupted sweep
started again skips finished cells."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.errors import ConfigError
from eaco_jax.outputs import to_jsonable, write_json
from eaco_jax.sweep.cells import Cell, expand_built, groups_of, with_params
from eaco_jax.sweep.spec import HOST_ROW_BYTES, SweepSpec, parse_spec


def plan(spec: SweepSpec | dict[str, Any], *, max_cells: int | None = None
         ) -> tuple[Any, list[Cell]]:
    """Check the spec (parsed once), expand and check every cell, and refuse a group whose
    rows (cells x seeds, one vmapped call) would not fit in memory; (run kind, cells)."""
    spec = parse_spec(spec, max_cells=max_cells)
    cells, built_for = expand_built(spec)
    check_memory(spec, cells, built_for)
    return spec.run_kind, cells


def check_memory(spec: SweepSpec, cells: list[Cell], built_for: dict[str, Any]) -> None:
    """Refuse, before anything is set up, a sweep whose largest group (its cells x seeds rows
    as one vmapped call) needs more than half of the memory available: each row's colony
    state (the driver's estimate) plus :data:`HOST_ROW_BYTES` of host memory."""
    from eaco_jax.driver.minimize import memory_limit, state_row_bytes
    from eaco_jax.runs.base import entered

    largest = max(groups_of(cells), key=len)
    rows = len(largest) * len(spec.seeds)
    built = built_for[largest[0].group_key()]
    state = 0
    if built.strategy is not None:
        params = built.params
        if dataclasses.is_dataclass(params):
            params = with_params(params, largest[0].params)
        with entered(built):
            state = state_row_bytes(built.strategy, built.problem, params)
    need, limit = rows * (state + HOST_ROW_BYTES), memory_limit()
    if need > limit // 2:
        raise ConfigError(
            f"the sweep's largest group needs about {need / 2**30:.1f} GiB ({len(largest):,} "
            f"cell(s) x {len(spec.seeds):,} seeds = {rows:,} rows of {state + HOST_ROW_BYTES:,} "
            f"bytes), more than half of the {limit / 2**30:.1f} GiB available; use fewer seeds, "
            "or fewer cells sharing the same settings")


def run_group(
    kind: Any,
    cells: list[Cell],
    seeds: list[int],
    *,
    progress: bool = False,
    checkpoint_dir: Path | None = None,
    checkpoint_every: int | None = None,
) -> dict[str, dict[str, Any]]:
    """Run cells that share static settings as one vmapped call; cell id -> cell record.

    Every row runs the whole budget (a target only marks success; it does not stop a sweep).
    """
    from eaco_jax.driver.minimize import Checkpointing, minimize
    from eaco_jax.runs.base import entered

    built = kind.build(kind.make_settings(dict(cells[0].args)))
    budget = {k: v for k, v in built.budget.items() if k != "target"}
    checkpointing = None
    if checkpoint_dir is not None:
        checkpointing = Checkpointing(checkpoint_dir, every=checkpoint_every)
    t0 = time.perf_counter()
    with entered(built):
        params = [with_params(built.params, c.params) for c in cells]
        result = minimize(built.problem, built.strategy, params=params, seed=seeds,
                          progress=progress, checkpointing=checkpointing, **budget)
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
            if kind.row_metrics is not None:
                row.update(kind.row_metrics(built, result, r))
            rows.append(row)
        records[cell.id] = {
            "cell": cell.id, "values": cell.values, "args": cell.args, "seeds": seeds,
            "group_cells": len(cells), "group_seconds": seconds,
            "compile_seconds": result.compile_seconds, "first_in_group": i == 0,
            "rows": rows,
        }
    return records


def cell_path(out: Path, cell: Cell) -> Path:
    return out / "cells" / f"{cell.id}.json"


def write_cell(out: Path, record: dict[str, Any]) -> None:
    """Atomically write one finished cell (tmp file + rename)."""
    write_json(out / "cells" / f"{record['cell']}.json", to_jsonable(record))


def read_cell(out: Path, cell: Cell) -> dict[str, Any] | None:
    path = cell_path(out, cell)
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text())
    except json.JSONDecodeError:
        return None  # a half-written cell file cannot exist (rename), but never trust it
    return record if record.get("cell") == cell.id else None


def run_local(kind: Any, todo: list[Cell], seeds: list[int], out: Path, *,
              every: int | None = None, progress: bool = False, total: int | None = None) -> None:
    """Run the unfinished cells ``todo`` group by group, writing each cell when its group ends."""
    total = len(todo) if total is None else total
    bar = _bar(progress, total, total - len(todo))
    try:
        for group in groups_of(todo):
            ck = None
            if every is not None:
                tag = hashlib.sha256("".join(c.id for c in group).encode()).hexdigest()[:10]
                ck = out / "checkpoints" / f"group-{tag}"
            for record in run_group(kind, group, seeds, progress=progress,
                                    checkpoint_dir=ck, checkpoint_every=every).values():
                write_cell(out, record)
            if bar is not None:
                bar.update(len(group))
    finally:
        if bar is not None:
            bar.close()


def _bar(progress: bool, total: int, initial: int):
    if not progress:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc="sweep", unit="cell")
