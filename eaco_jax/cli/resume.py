"""``eaco resume DIR``: continue a checkpointed run to its original budget.

Iteration and evaluation budgets continue where the run stopped; a time budget
(``--max-seconds``, either clock) starts again from the resume.

Every run command stores its run kind, settings and checkpoint interval in its checkpoints;
:func:`eaco_jax.runs.resume` reads them back and runs the kind again from the checkpoint
(bit-identical to an unbroken run), returning the record the original command would have.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from eaco_jax.cli.common import emit_json, guarded


def register(app: typer.Typer) -> None:
    @app.command()
    @guarded
    def resume(
        directory: Annotated[Path, typer.Argument(help="checkpoint folder of a run")],
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
        quiet: Annotated[bool, typer.Option("--quiet", help="no progress bar")] = False,
    ) -> None:
        """Continue an interrupted run from its newest checkpoint to its original budget (a
        --max-seconds budget starts again)."""
        from eaco_jax.runs import checkpoint_kind
        from eaco_jax.runs import resume as resume_run

        kind = checkpoint_kind(directory)
        record = resume_run(directory, progress=not (quiet or json_out))
        if json_out:
            emit_json(record)
        elif not quiet and kind.summary is not None:  # as the run's own command prints it
            typer.echo(kind.summary(record))
        elif not quiet:
            for key, value in record.items():
                if not isinstance(value, list | dict):
                    typer.echo(f"{key}: {value}")
