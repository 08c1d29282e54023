"""A finished sweep's tables: ``table.csv`` / ``table.json`` (one row per cell x seed),
``summary.json`` (one row per cell) and ``summary.png`` (best cost over seeds per cell)."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.outputs import write_json
from eaco_jax.sweep.cells import Cell, groups_of
from eaco_jax.sweep.spec import SweepSpec


def summarise(record: dict[str, Any]) -> dict[str, Any]:
    """One cell's statistics over its seeds."""
    costs = np.array([np.inf if r["best_cost"] is None else r["best_cost"]
                      for r in record["rows"]], dtype=np.float64)
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
    out: Path, spec: SweepSpec, cells: list[Cell], records: list[dict[str, Any]],
    wall: float, ran: int,
) -> dict[str, Any]:
    """table.csv / table.json (cell x seed rows), summary.json and summary.png."""
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
        "name": spec.name or spec.command or spec.kind_ref,
        "out": str(out), "cells": len(cells), "seeds": list(spec.seeds), "runs": len(rows),
        "cells_run_now": ran, "wall_seconds": wall,
        "compile_seconds": sum(float(r.get("compile_seconds") or 0.0) for r in records
                               if r.get("first_in_group", True)),
        "groups": len(groups_of(cells)),
        "table_csv": str(out / "table.csv"), "table_json": str(out / "table.json"),
        "plot": str(out / "summary.png"), "summary": summary,
    }
    write_json(out / "summary.json", record)
    plot_summary(out / "summary.png", records, record["name"])
    return record


def plot_summary(path: Path, records: list[dict[str, Any]], title: Any) -> None:
    """Box plot of every cell's best cost over seeds."""
    from eaco_jax.plots import save_figure, subplots

    data = [[r["best_cost"] for r in rec["rows"]
             if r["best_cost"] is not None and math.isfinite(r["best_cost"])] or [np.nan]
            for rec in records]
    labels = [", ".join(f"{k}={_fmt(v)}" for k, v in rec["values"].items()) or rec["cell"]
              for rec in records]
    fig, ax = subplots(figsize=(max(5.0, 0.6 * len(records) + 2), 4.5))
    ax.boxplot(data)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("best cost over seeds")
    ax.set_title(f"sweep {title}")
    save_figure(fig, path)


def _fmt(v: Any) -> str:
    return f"{v:.3g}" if isinstance(v, float) else str(v)
