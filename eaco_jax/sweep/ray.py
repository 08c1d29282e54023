"""Sweep cells on a Ray cluster: one task per cell, each cell checkpointed.

``eaco sweep SPEC --backend ray`` sends every unfinished cell of the sweep to Ray as one task
(all seeds of the cell vmapped in it). A task checkpoints its run into
``OUT/checkpoints/<cell id>`` (every ``checkpoint_every`` iterations of the spec, and at the
end) and the driver writes ``OUT/cells/<cell id>.json`` when the task returns, so a lost worker
costs at most its own cell: Ray retries the task (``max_retries``), which resumes from the
cell's newest checkpoint, and a restarted sweep skips every finished cell.

On a multi-machine cluster ``OUT`` must be on a file system all nodes share (for the
checkpoints); the cell results themselves travel back through Ray. Connect to a running
cluster with ``address="auto"`` (or ``ray://...``); without an address a local Ray instance is
started with ``num_cpus`` workers.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from eaco_jax.errors import ConfigError
from eaco_jax.sweep.cells import Cell
from eaco_jax.sweep.local import run_group, write_cell
from eaco_jax.sweep.spec import SweepSpec, resolve_kind


def _run_cell(command: str | None, kind_ref: str | None, cell: dict[str, Any],
              seeds: list[int], out: str, every: int | None) -> dict[str, Any]:
    """Body of one Ray task: build, run (resuming from the cell's checkpoint), return record.

    The run kind travels by name (``command`` or ``kind_ref``), imported in the worker."""
    c = Cell(**cell)
    ck = Path(out) / "checkpoints" / c.id
    return run_group(resolve_kind(command, kind_ref), [c], seeds, checkpoint_dir=ck,
                     checkpoint_every=every)[c.id]


def run_cells_on_ray(
    spec: SweepSpec,
    cells: list[Cell],
    seeds: list[int],
    out: Path,
    *,
    progress: bool = False,
    address: str | None = None,
    num_cpus: int | None = None,
    max_retries: int = 3,
    runtime_env: dict[str, Any] | None = None,
) -> None:
    """Run ``cells`` as Ray tasks and write each finished cell's file as it arrives."""
    try:
        import ray
    except ImportError:
        raise ConfigError(
            "the ray backend needs Ray: pip install 'eaco-jax[ray]' (or pip install ray)"
        ) from None
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = dict(include_dashboard=False, log_to_driver=False)
        if address:
            kwargs["address"] = address
        elif num_cpus:
            kwargs["num_cpus"] = num_cpus
        if runtime_env:
            kwargs["runtime_env"] = runtime_env
        ray.init(**kwargs)
        started = True
    task = ray.remote(num_cpus=1, max_retries=max_retries)(_run_cell)
    every = spec.checkpoint_every
    out = Path(out).absolute()
    pending = {
        task.remote(spec.command, spec.kind_ref, dataclasses.asdict(c), seeds, str(out),
                    every): c for c in cells
    }
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(cells), desc="sweep (ray)", unit="cell")
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                pending.pop(ref)
                write_cell(out, ray.get(ref))
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        if started:
            ray.shutdown()
