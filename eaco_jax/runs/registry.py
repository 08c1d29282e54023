"""The registry of run kinds (``get("tsp")``), and ``resume`` of a checkpointed run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from eaco_jax.errors import CheckpointError, ConfigError
from eaco_jax.runs import constrained, gait, gait_front, path, tsp, walk
from eaco_jax.runs.base import RunKind

_KINDS: dict[str, RunKind] = {
    k.name: k for k in (tsp.KIND, constrained.KIND, path.KIND, gait.KIND, gait.EVAL_KIND,
                        gait_front.KIND, walk.KIND)}


def register(kind: RunKind) -> RunKind:
    """Add a run kind of your own (its name becomes a sweep ``command``)."""
    _KINDS[kind.name] = kind
    return kind


def kinds() -> dict[str, RunKind]:
    """Every run kind by name."""
    return dict(_KINDS)


def get(name: str) -> RunKind:
    """The run kind called ``name``; a ConfigError line lists the known ones."""
    if name not in _KINDS:
        raise ConfigError(f"unknown run kind {name!r}; known: {', '.join(sorted(_KINDS))}")
    return _KINDS[name]


def checkpoint_kind(directory: str | Path) -> RunKind:
    """The run kind whose command wrote the checkpoint in ``directory`` (its ``summary``
    prints a resumed run as the command would have)."""
    return _stored_run(Path(directory))[0]


def _stored_run(directory: Path) -> tuple[RunKind, dict[str, Any]]:
    """The run kind and the run info stored in a checkpoint; CheckpointError lines."""
    if not directory.is_dir():
        raise CheckpointError(f"checkpoint folder {directory} does not exist")
    info = _stored_meta(directory).get("run_info") or {}
    name, values = info.get("kind"), info.get("settings")
    if not name or not isinstance(values, dict):
        raise CheckpointError(
            f"checkpoint in {directory} has no stored run kind (it was written by the Python "
            "API, not an eaco command); resume it by calling minimize() again with the same "
            "Checkpointing")
    try:
        kind = get(str(name))
    except ConfigError:
        raise CheckpointError(
            f"checkpoint in {directory} was written by run kind {name!r}, which this "
            f"installation does not provide (known: {', '.join(sorted(kinds()))})") from None
    return kind, info


def resume(directory: str | Path, *, progress: bool = False) -> dict[str, Any]:
    """Continue the checkpointed run in ``directory`` to its original budget (iterations and
    evaluations continue; a time budget starts again); its record."""
    from eaco_jax.driver.minimize import Checkpointing

    directory = Path(directory)
    kind, info = _stored_run(directory)
    values = info["settings"]
    settings = kind.make_settings(values, where=f"checkpoint in {directory}: ")
    checkpointing = Checkpointing(directory, every=info.get("checkpoint_every"),
                                  run_info=info)
    return kind.run(settings, progress=progress, checkpointing=checkpointing)


def _stored_meta(directory: Path) -> dict[str, Any]:
    """The newest readable checkpoint's metadata; where there is none (never saved, or every
    step corrupt and moved aside), one line naming the command that starts the run again
    (from ``run.json``)."""
    from eaco_jax.driver.checkpoint import all_steps, read_meta, read_run_info

    command = read_run_info(directory).get("command")
    if command and not all_steps(directory):
        corrupt = directory / "corrupt"
        if corrupt.is_dir() and any(corrupt.iterdir()):
            raise CheckpointError(f"every checkpoint in {directory} was corrupt (moved to "
                                  f"{corrupt}); start again with: {command}")
        raise CheckpointError(f"no checkpoint in {directory} (the run stopped before its "
                              f"first save); start again with: {command}")
    try:
        return read_meta(directory)
    except CheckpointError as err:
        if command:
            raise CheckpointError(f"{err}; it was started with: {command}") from None
        raise
