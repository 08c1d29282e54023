"""``eaco sweep SWEEP.yaml``: settings x seeds for a run kind, batched, resumable.

The file format is documented in ``docs/sweeps.md`` (and :mod:`eaco_jax.sweep.spec`); its keys
are the run command's flags (``ants``, ``iterations``, ...) and the strategy's Params fields.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from eaco_jax.cli.common import emit_json, guarded


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def sweep(
        spec_file: Annotated[Path, typer.Argument(help="sweep YAML file")],
        executor: Annotated[str, typer.Option(
            help="local (vmapped groups) or ray (one task per cell)")] = "local",
        out: Annotated[Path | None, typer.Option(help="output folder")] = None,
        address: Annotated[str | None, typer.Option(help="Ray cluster address")] = None,
        workers: Annotated[int | None, typer.Option(help="local Ray CPUs (workers)")] = None,
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
        max_cells: Annotated[int | None, typer.Option(
            help="most cells the sweep may have (default: the file's max_cells, else "
                 "100,000)")] = None,
    ) -> None:
        """Run a hyper-parameter sweep; an interrupted sweep resumes where it stopped.

        YAML keys: command (tsp|constrained|path|gait) or kind ("module:RUNKIND"), args
        (fixed settings: the command's flags), seeds (int or list), cells (list of settings)
        and/or grid (lists, crossed), or random (n, seed, space), checkpoint_every,
        max_cells. Swept Params fields run as one vmapped call. Format: docs/sweeps.md;
        example: experiments/sweeps/table3_g01.yaml.
        """
        from eaco_jax.sweep import load_spec, run_sweep

        spec = load_spec(spec_file, max_cells=max_cells)
        folder = out or Path("sweeps") / spec_file.stem
        ray_options = {"address": address, "num_cpus": workers} if executor == "ray" else None
        record = run_sweep(spec, folder, backend=executor, progress=not (quiet or json_out),
                           ray_options=ray_options)
        if json_out:
            emit_json(record)
            return
        keys = [k for k in record["summary"][0] if k != "cell"] if record["summary"] else []
        typer.echo("  ".join(f"{k:>12}" for k in keys))
        for row in record["summary"]:
            typer.echo("  ".join(f"{_fmt(row.get(k)):>12}" for k in keys))
        typer.echo(f"{record['runs']} runs in {record['wall_seconds']:.1f} s -> {record['out']}")


def _fmt(value: object) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)
