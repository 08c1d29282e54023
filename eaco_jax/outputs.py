"""Writing results: plain-JSON conversion, JSON files, per-iteration CSV (one neutral module
that the runs, the sweeps and the command line share)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def to_jsonable(value: Any) -> Any:
    """``value`` as plain JSON: the one rule for every file and record the package writes
    (results, sweep cells, checkpoint identities and run info).

    Dict keys become strings and tuples lists; numpy/jax arrays become nested lists and numpy
    scalars Python scalars; a ``Path`` its string; a non-finite float ``null`` (strict JSON has
    no NaN or Infinity); str, int, bool, None and finite floats stay; anything else becomes its
    ``repr`` (a label that compares equal for equal configurations, e.g. a strategy nested in
    another; never an error). Applying it twice changes nothing.
    """
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if hasattr(value, "shape") and hasattr(value, "dtype"):
        value = np.asarray(value)
        return to_jsonable(value.tolist()) if value.ndim else to_jsonable(value.item())
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, str | int | bool) or value is None:
        return value
    if isinstance(value, np.generic):
        return to_jsonable(value.item())
    if isinstance(value, Path):
        return str(value)
    return repr(value)


def write_json(path: str | Path, record: Any) -> Path:
    """``record`` as indented JSON at ``path`` (folders created), atomically (tmp + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(to_jsonable(record), indent=2) + "\n")
    tmp.replace(path)
    return path


def write_history_csv(path: str | Path, history: dict[str, Any]) -> Path:
    """Per-iteration history as CSV: an ``iteration`` column (1-based), then one per metric."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = list(history)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["iteration", *keys])
        if keys:
            for i in range(len(np.asarray(history[keys[0]]))):
                writer.writerow([i + 1, *(np.asarray(history[k])[i].item() for k in keys)])
    return path
