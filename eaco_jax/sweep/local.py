"""Running cells on this machine: each group of cells as one vmapped call; each finished cell
is written to ``OUT/cells/<cell id>.json`` as soon as its group ends, so an interrupted sweep
started again skips finished cells."""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.outputs import to_jsonable, write_json
from eaco_jax.sweep.cells import Cell, expand, groups_of, with_params
from eaco_jax.sweep.spec import run_kind, validate_spec


def plan(spec: dict[str, Any]) -> tuple[Any, list[Cell]]:
    """Validate the spec, find its run kind and expand (and check) every cell."""
    spec = validate_spec(spec)
    kind = run_kind(spec)
    return kind, expand(spec, kind)


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
