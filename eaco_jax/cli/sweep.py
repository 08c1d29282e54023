"""``eaco sweep SWEEP.yaml``: hyper-parameters x seeds for a run command, batched, resumable.

The YAML file::

    name: table3_g01            # optional, used in titles and the summary
    command: constrained        # run command whose builder makes problem + strategy
                                # (constrained, tsp); or builder: "package.module:function"
    args:                       # fixed arguments of that command (static configuration)
      problem: g01
      iterations: 300
      num_ants: 20
    seeds: 10                   # 0..9, or an explicit list [3, 7, 11]
    cells:                      # listed settings (each one cell) ...
      - {q0: 0.2, rho: 0.1, p_crossover: 0.2, p_mutation: 0.2}
      - {q0: 0.8, rho: 0.3, p_crossover: 0.5, p_mutation: 0.6}
    grid:                       # ... and/or a grid (cartesian product, crossed with cells)
      locality: [0.1, 0.2]
    # random:                   # or instead: n random settings
    #   n: 20
    #   seed: 0
    #   space: {q0: [0.1, 0.9], rho: {low: 0.01, high: 1.0, log: true},
    #           num_ants: {choice: [20, 40]}}
    checkpoint_every: 50        # optional: checkpoint every run (resume inside a cell)

A swept key that is a field of the strategy's Params (``q0``, ``rho``, ``p_crossover``, ...) is
traced: all cells that differ only in such keys run as ONE vmapped, jitted call. Any other key
is a static argument of the command (``num_ants``, ``problem``, ``iterations``, ...): cells with
different static arguments run one group after another (or one Ray task per cell with
``--backend ray``).

Results: ``OUT/cells/*.json`` (one per finished cell; a rerun skips them), ``OUT/table.csv`` and
``OUT/table.json`` (one row per cell x seed), ``OUT/summary.json`` and ``OUT/summary.png``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from eaco_jax.cli.common import emit_json, guarded


def load_spec(path: Path) -> dict:
    """Read a sweep YAML file (one-line errors for missing or malformed files)."""
    import yaml

    if not path.is_file():
        raise FileNotFoundError(f"sweep file {path} does not exist")
    try:
        spec = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        first = str(err).splitlines()[0]
        raise ValueError(f"sweep file {path} is not valid YAML: {first}") from None
    if not isinstance(spec, dict):
        raise ValueError(f"sweep file {path} must hold a mapping (name, command, args, ...)")
    return spec


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def sweep(
        spec_file: Annotated[Path, typer.Argument(help="sweep YAML file")],
        backend: Annotated[str, typer.Option(help="local (vmapped groups) or ray")] = "local",
        out: Annotated[Path | None, typer.Option(help="output folder")] = None,
        address: Annotated[str | None, typer.Option(help="Ray cluster address")] = None,
        workers: Annotated[int | None, typer.Option(help="local Ray CPUs (workers)")] = None,
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
    ) -> None:
        """Run a hyper-parameter sweep; an interrupted sweep resumes where it stopped.

        YAML keys: command (constrained|tsp|gait) or builder ("module:function"), args (fixed
        command arguments), seeds (int or list), cells (list of settings) and/or grid (lists,
        crossed), or random (n, seed, space), checkpoint_every. Swept Params fields run as
        one vmapped call. Full format: the docstring of eaco_jax/cli/sweep.py; example:
        experiments/sweeps/table3_g01.yaml.
        """
        from eaco_jax.sweep import run_sweep

        spec = load_spec(spec_file)
        folder = out or Path("sweeps") / spec_file.stem
        ray_options = {"address": address, "num_cpus": workers} if backend == "ray" else None
        record = run_sweep(spec, folder, backend=backend, progress=not (quiet or json_out),
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
