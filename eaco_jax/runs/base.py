"""What a run kind is, and the registry of them.

A run kind (``tsp``, ``constrained``, ``path``, ``gait``, ``gait-eval``) owns one kind of run end
to end, as brax's ``train`` functions do:

* ``Settings``: a frozen dataclass with the defaults. Its field names are the command-line flags
  (``ants`` -> ``--ants``), the keys of a sweep file and what ``eaco resume`` reads back from a
  checkpoint; each field's help text (``setting(..., help=)``) is what ``--help`` prints.
  ``__post_init__`` checks every value and raises one :class:`~eaco_jax.errors.ConfigError` line.
* ``build(settings) -> Built``: the problem, strategy, params and budget (no running).
* ``run(settings, progress=, checkpointing=) -> record``: build, minimise, write the outputs
  into ``settings.out`` (if set) and return the JSON record.
* ``row_metrics(built, result, row) -> dict``: the columns one result row adds to a sweep table.

The command line and the sweeps call these and re-derive nothing.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from eaco_jax.errors import ConfigError


def setting(default: Any, help: str, *, choices: tuple[str, ...] | None = None,
            positional: bool = False, metavar: str | None = None) -> Any:
    """A Settings field with its help text (and, for strings, the allowed values)."""
    meta = {"help": help, "choices": choices, "positional": positional, "metavar": metavar}
    return dataclasses.field(default=default, metadata=meta)


def check_choices(settings: Any) -> None:
    """One ConfigError line for a string setting outside its ``choices``."""
    for f in dataclasses.fields(settings):
        choices = f.metadata.get("choices")
        value = getattr(settings, f.name)
        if choices and value not in choices:
            raise ConfigError(f"{f.name}={value!r} is not one of {', '.join(choices)}")


def check_positive(settings: Any, *names: str) -> None:
    """One ConfigError line for a count that is not >= 1."""
    for name in names:
        value = getattr(settings, name)
        if value is not None and (isinstance(value, bool) or int(value) != value or value < 1):
            raise ConfigError(f"{name} must be an integer >= 1, got {value!r}")


@dataclasses.dataclass
class Built:
    """A run kind's problem, strategy and budget, built from its settings (nothing run yet).

    ``context`` (if set) is entered around building and running, e.g.
    :func:`eaco_jax.problems.float64` for the constrained kind.
    """

    problem: Any
    strategy: Any
    params: Any
    budget: dict[str, Any]
    context: Callable[[], contextlib.AbstractContextManager] | None = None
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class RunKind:
    """One kind of run: settings, build, run and its sweep columns (see the module docstring)."""

    name: str
    settings: type
    build: Callable[[Any], Built]
    run: Callable[..., dict[str, Any]]
    row_metrics: Callable[[Built, Any, int], dict[str, Any]] | None = None
    summary: Callable[[dict[str, Any]], str] | None = None
    resumable: bool = True

    def make_settings(self, values: dict[str, Any], where: str = "") -> Any:
        """``Settings(**values)``, with unknown keys named next to the valid ones."""
        valid = [f.name for f in dataclasses.fields(self.settings)]
        unknown = sorted(set(values) - set(valid))
        if unknown:
            raise ConfigError(
                f"{where}unknown {self.name} setting(s) {unknown}; valid: {', '.join(valid)}")
        try:
            return self.settings(**values)
        except ConfigError as err:
            if not where:
                raise
            raise ConfigError(f"{where}{err}") from None


def settings_dict(settings: Any) -> dict[str, Any]:
    """The settings as plain JSON values (what a checkpoint stores for ``resume``)."""
    return {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}


@contextlib.contextmanager
def entered(built: Built) -> Iterator[None]:
    """Enter ``built.context`` if it has one."""
    if built.context is None:
        yield
    else:
        with built.context():
            yield


def checkpointing_for(kind: str, settings: Any, directory: str | Path | None,
                      every: int | None) -> Any:
    """A :class:`~eaco_jax.driver.minimize.Checkpointing` storing what ``resume`` needs."""
    from eaco_jax.driver.minimize import Checkpointing

    if directory is None:
        if every is not None:
            raise ConfigError("--checkpoint-every needs --checkpoint-dir")
        return None
    if every is not None and every < 1:
        raise ConfigError(f"--checkpoint-every must be >= 1, got {every}")
    info = {"kind": kind, "settings": settings_dict(settings), "checkpoint_every": every}
    return Checkpointing(directory, every=every, run_info=info)


def settings_table(kind: RunKind) -> str:
    """The kind's settings as a Markdown table (docs/sweeps.md is checked against it)."""
    import typing

    hints = typing.get_type_hints(kind.settings)
    rows = [f"| `{kind.name}` setting | type | default | meaning |", "|---|---|---|---|"]
    for f in dataclasses.fields(kind.settings):
        hint = getattr(hints[f.name], "__name__", None) or str(hints[f.name])
        hint = hint.replace(" | ", " or ")
        text = f.metadata.get("help", "")
        if f.metadata.get("choices"):
            text += f" ({' / '.join(f.metadata['choices'])})"
        if f.metadata.get("positional"):
            text += "; the command's argument"
        rows.append(f"| `{f.name}` | {hint} | `{f.default!r}` | {text} |")
    return "\n".join(rows)
