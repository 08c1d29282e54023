"""``run_sweep``: plan the sweep, run its unfinished cells here or on Ray, write the tables."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from eaco_jax.errors import ConfigError, Interrupted
from eaco_jax.sweep.local import plan, read_cell, run_local
from eaco_jax.sweep.report import write_tables
from eaco_jax.sweep.spec import SweepSpec, parse_spec


def run_sweep(
    spec: SweepSpec | dict[str, Any],
    out: str | Path,
    *,
    backend: str = "local",
    progress: bool = False,
    ray_options: dict[str, Any] | None = None,
    max_cells: int | None = None,
) -> dict[str, Any]:
    """Run (or finish) a sweep into folder ``out``; returns the summary record.

    ``spec``: a mapping (checked here, once) or a :class:`SweepSpec`; ``max_cells`` overrides
    the spec's limit on the number of cells."""
    if backend not in ("local", "ray"):
        raise ConfigError(f"unknown sweep backend {backend!r}; use 'local' or 'ray'")
    out = Path(out)
    spec = parse_spec(spec, max_cells=max_cells)
    kind, cells = plan(spec)
    seeds = list(spec.seeds)
    every = spec.checkpoint_every
    todo = [c for c in cells if read_cell(out, c) is None]
    out.mkdir(parents=True, exist_ok=True)
    (out / "spec.json").write_text(json.dumps(spec.to_dict(), indent=1, default=str) + "\n")
    t0 = time.perf_counter()
    if backend == "local":
        try:
            run_local(kind, todo, seeds, out, every=every, progress=progress, total=len(cells))
        except Interrupted as err:
            finished = sum(read_cell(out, c) is not None for c in cells)
            hint = ("; the interrupted group resumes from its checkpoint" if every else
                    "; add checkpoint_every to the spec to resume inside a group")
            raise Interrupted(
                f"sweep interrupted: {finished} of {len(cells)} cells finished in {out}; run "
                f"the same sweep again to continue (finished cells are skipped{hint})",
                err.result) from None
    else:
        from eaco_jax.sweep.ray import run_cells_on_ray

        run_cells_on_ray(spec, todo, seeds, out, progress=progress, **(ray_options or {}))
    wall = time.perf_counter() - t0
    records = [read_cell(out, c) for c in cells]
    missing = [c.id for c, r in zip(cells, records, strict=True) if r is None]
    if missing:
        raise RuntimeError(f"sweep cells {missing} did not finish; run the sweep again")
    return write_tables(out, spec, cells, records, wall, ran=len(todo))
