"""The run commands (``tsp``, ``constrained``, ``path``, ``gait``, ``gait-eval``), generated from
the run kinds' settings: every settings field is a flag of the same name (``ants`` ->
``--ants``) with the field's default and help, so the command line, the sweep keys and
``eaco resume`` cannot drift apart. Each command adds ``--json``, ``--quiet`` and, for
resumable kinds, ``--checkpoint-dir`` / ``--checkpoint-every``.
"""

from __future__ import annotations

import dataclasses
import inspect
import typing
from pathlib import Path
from typing import Annotated, Any

import typer

from eaco_jax.cli.common import emit_json, guarded
from eaco_jax.runs.base import RunKind, checkpointing_for

COMMON = ("json_out", "quiet", "checkpoint_dir", "checkpoint_every")


def _option(name: str, f: dataclasses.Field, hint: Any) -> inspect.Parameter:
    meta = f.metadata
    help_text = meta.get("help", "")
    if meta.get("choices"):
        help_text += f" ({'|'.join(meta['choices'])})"
    flag = "--" + name.replace("_", "-")
    if meta.get("positional"):
        info = typer.Argument(metavar=meta.get("metavar"), help=help_text)
        return inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                 annotation=Annotated[hint, info])
    if hint is bool or hint == (bool | None):
        info = typer.Option(f"{flag}/--no-{name.replace('_', '-')}", help=help_text)
    else:
        info = typer.Option(flag, help=help_text)
    return inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=f.default,
                             annotation=Annotated[hint, info])


def _common(resumable: bool) -> list[inspect.Parameter]:
    kw = inspect.Parameter.KEYWORD_ONLY
    out = [
        inspect.Parameter("json_out", kw, default=False, annotation=Annotated[
            bool, typer.Option("--json", help="print one JSON record (no progress bar)")]),
        inspect.Parameter("quiet", kw, default=False, annotation=Annotated[
            bool, typer.Option("--quiet", help="no progress bar, no summary")]),
    ]
    if resumable:
        out += [
            inspect.Parameter("checkpoint_dir", kw, default=None, annotation=Annotated[
                Path | None, typer.Option(help="checkpoint folder (continue: eaco resume DIR)")]),
            inspect.Parameter("checkpoint_every", kw, default=None, annotation=Annotated[
                int | None, typer.Option(help="iterations between checkpoints")]),
        ]
    return out


def add_run_command(app: typer.Typer, kind: RunKind, doc: str) -> None:
    """Register ``eaco <kind>`` with one flag per settings field."""
    hints = typing.get_type_hints(kind.settings)
    fields = dataclasses.fields(kind.settings)
    params = [_option(f.name, f, hints[f.name]) for f in fields if f.metadata.get("positional")]
    params += [_option(f.name, f, hints[f.name]) for f in fields
               if not f.metadata.get("positional")]
    params += _common(kind.resumable)

    def command(**kwargs: Any) -> None:
        json_out, quiet = kwargs.pop("json_out"), kwargs.pop("quiet")
        ckpt_dir, ckpt_every = kwargs.pop("checkpoint_dir", None), kwargs.pop(
            "checkpoint_every", None)
        values = {k: (str(v) if isinstance(v, Path) else v) for k, v in kwargs.items()}
        settings = kind.make_settings(values)
        checkpointing = checkpointing_for(kind.name, settings, ckpt_dir, ckpt_every)
        record = kind.run(settings, progress=not (json_out or quiet),
                          checkpointing=checkpointing)
        if json_out:
            emit_json(record)
        elif not quiet and kind.summary is not None:
            typer.echo(kind.summary(record))

    command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    command.__doc__ = doc
    command.__name__ = kind.name.replace("-", "_")
    app.command(kind.name)(guarded(command))


DOCS = {
    "tsp": "Solve a TSPLIB instance with the EACO colony (MMAS-style defaults, 2-opt).",
    "constrained": "Solve a constrained problem with continuous EACO (CEC2006 success 1e-4).",
    "path": "Plan the shortest collision-free path from start to goal among obstacles.",
    "gait": "Optimise a walking gait with the EACO colony on batched physics.",
    "gait-eval": "Re-simulate stored gait parameters: speed, distance, fall, drift.",
    "gait-front": "Search the Pareto front of walking speed against endurance or electrical CoT.",
    "walk": "Plan a route through a scene, then walk it with the NAO on native MuJoCo or MJX.",
}


def register(app: typer.Typer) -> None:
    from eaco_jax.runs import kinds

    for name, kind in kinds().items():
        add_run_command(app, kind, DOCS.get(name, f"Run a {name} run."))
