"""``eaco resume DIR``: continue a checkpointed run to its original budget.

Every run command (tsp, constrained, gait) stores ``run_info={"command": name, "args": {...}}``
in its checkpoints. Resume reads it from the newest complete checkpoint, looks the command's
runner up in :data:`eaco_jax.cli.common.RUNNERS` and calls it with the stored arguments (with
``checkpoint_dir`` pointing at DIR), so the run continues from the checkpoint, bit-identical to an
unbroken one, and prints the record the original command would have printed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from eaco_jax.cli.common import RUNNERS, emit_json, guarded


def resume_run(directory: str | Path, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Re-run the command stored in the checkpoint in ``directory``; returns its JSON record."""
    from eaco_jax.driver.checkpoint import CheckpointError, read_meta

    directory = Path(directory)
    if not directory.is_dir():
        raise FileNotFoundError(f"checkpoint folder {directory} does not exist")
    info = read_meta(directory).get("run_info") or {}
    command, args = info.get("command"), info.get("args")
    if not command or not isinstance(args, dict):
        raise CheckpointError(
            f"checkpoint in {directory} has no stored command (it was written by the Python API, "
            "not an eaco command); resume it by calling minimize() again with checkpoint_dir"
        )
    if command not in RUNNERS:
        known = ", ".join(sorted(RUNNERS)) or "none"
        raise CheckpointError(
            f"checkpoint in {directory} was written by command {command!r}, which this "
            f"installation does not provide (known: {known})"
        )
    args = dict(args)
    args["checkpoint_dir"] = str(directory)
    args.update(overrides or {})
    return RUNNERS[command](**args)


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def resume(
        directory: Annotated[Path, typer.Argument(help="checkpoint folder of a run")],
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
    ) -> None:
        """Continue an interrupted run from its newest checkpoint to its original budget."""
        overrides: dict[str, Any] = {}
        if quiet or json_out:
            overrides = _quiet_overrides(directory)
        record = resume_run(directory, overrides)
        if json_out:
            emit_json(record)
        else:
            for key, value in record.items():
                if not isinstance(value, (list, dict)):
                    typer.echo(f"{key}: {value}")


def _quiet_overrides(directory: Path) -> dict[str, Any]:
    """Switch off the progress bar in the stored arguments, whichever flag the command uses."""
    from eaco_jax.driver.checkpoint import read_meta

    args = (read_meta(directory).get("run_info") or {}).get("args") or {}
    out: dict[str, Any] = {}
    if "quiet" in args:
        out["quiet"] = True
    if "progress" in args:
        out["progress"] = False
    return out
