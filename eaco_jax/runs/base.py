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
import re
from collections.abc import Callable, Iterator, Mapping
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
    """One ConfigError line for a count that is not an integer in 1..2**31-1."""
    for name in names:
        value = getattr(settings, name)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int | float) or int(value) != value:
            raise ConfigError(f"{name} must be an integer >= 1, got {value!r}")
        if not 1 <= value <= 2**31 - 1:
            raise ConfigError(f"{name}={value} is outside its range 1..2147483647")


#: settings that are PRNG seeds: integers in 0..2**32-1
SEED_FIELDS = ("seed", "world_seed")


def check_types(settings: Any) -> None:
    """One ConfigError line for a value of the wrong type (from a sweep file or the API),
    a seed outside 0..2**32-1 or a non-finite or negative budget in seconds."""
    import math
    import typing

    hints = typing.get_type_hints(type(settings))
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        hint = hints.get(f.name)
        args = set(typing.get_args(hint)) or {hint}
        if value is None:
            if type(None) not in args:
                raise ConfigError(f"{f.name} needs a value (got None)")
            continue
        if bool in args:
            ok = isinstance(value, bool) or value in (0, 1)
            want = "true or false"
        elif int in args:
            ok = not isinstance(value, bool) and (
                isinstance(value, int) or (isinstance(value, float) and value.is_integer()))
            want = "an integer"
        elif float in args:
            ok = (not isinstance(value, bool) and isinstance(value, int | float)
                  and math.isfinite(value))
            want = "a finite number"
        elif str in args:
            ok = isinstance(value, str)
            want = "a string"
        else:
            continue
        if not ok:
            raise ConfigError(f"{f.name}={value!r} must be {want}")
        if f.name in SEED_FIELDS and not 0 <= int(value) <= 2**32 - 1:
            raise ConfigError(f"{f.name}={value} is outside its range 0..4294967295")
        if f.name == "max_seconds" and not value > 0:
            raise ConfigError(f"max_seconds must be > 0, got {value}")


def check_settings(settings: Any, *positive: str) -> None:
    """Types, choices and counts of a Settings object (one ConfigError line)."""
    check_types(settings)
    check_choices(settings)
    check_positive(settings, *positive)


def parse_overrides(text: str | None) -> dict[str, Any]:
    """``"q0=0.9,use_elitist=true"`` -> ``{"q0": 0.9, "use_elitist": True}``."""
    if not text:
        return {}
    out: dict[str, Any] = {}
    for item in text.split(","):
        if not item.strip():
            continue
        key, sep, raw = item.partition("=")
        key, raw = key.strip(), raw.strip()
        if not sep or not key:
            raise ConfigError(f"params: {item!r} is not KEY=VALUE (e.g. 'q0=0.9,use_chaos=true')")
        low = raw.lower()
        if low in ("true", "yes", "on"):
            out[key] = True
        elif low in ("false", "no", "off"):
            out[key] = False
        else:
            try:
                out[key] = float(raw)
            except ValueError:
                raise ConfigError(f"params: {key}={raw!r} is not a number or true/false") from None
    return out


def params_with(base: Any, overrides: dict[str, Any], where: str = "") -> Any:
    """``base`` Params with ``overrides``; every field an array of its default's dtype (so
    settings stack into one batch; booleans stay booleans: 1/0 mean on/off). Unknown fields
    are listed with the valid ones; values that are not numbers are one line."""
    import jax.numpy as jnp
    import numpy as np

    names = [f.name for f in dataclasses.fields(base)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ConfigError(f"{where}unknown {type(base).__name__} field(s) {unknown}; valid: "
                          f"{', '.join(names)}")
    changes = {}
    for name in names:
        value = getattr(base, name)
        dtype = jnp.asarray(value).dtype
        if name in overrides:
            value = overrides[name]
            try:
                np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                raise ConfigError(f"{where}{name}={value!r} is not a number") from None
        changes[name] = jnp.asarray(value, dtype=dtype)
    return base.replace(**changes)


def switch_names(switch: str) -> list[str]:
    """The field names a switch of ``inactive_params`` reads, in order (``"repair_steps > 0 or
    refine_ants > 0"`` -> repair_steps, refine_ants; quoted values and keywords skipped)."""
    bare = re.sub(r"'[^']*'|\"[^\"]*\"", "", switch)
    words = re.findall(r"[A-Za-z_]\w*", bare)
    return list(dict.fromkeys(w for w in words if w not in ("and", "or", "not")))


def refuse_inactive(strategy: Any, params: Any, names: Any, where: str = "",
                    fixed: Mapping[str, str] | None = None,
                    command: str = "this command") -> None:
    """One ConfigError line for a set Params field that these switches leave unused (a
    setting that would change nothing), as a sweep refuses sweeping it. The line names the
    switch that makes the field act, unless ``command`` holds every name in that switch
    fixed (``fixed``: name -> why, for switches its user cannot set): then it says why."""
    dead = strategy.inactive_params(params)
    fixed = fixed or {}
    for name in names:
        if name not in dead:
            continue
        held = switch_names(dead[name])
        if held and all(h in fixed for h in held):
            why = "; ".join(dict.fromkeys(fixed[h] for h in held))
            raise ConfigError(f"{where}{name} has no effect in {command} ({why}); drop it")
        raise ConfigError(f"{where}{name} has no effect unless {dead[name]} (set that "
                          f"too, or drop {name})")


def params_from(strategy: Any, problem: Any, text: str | None,
                where: str = "--params: ", fixed: Mapping[str, str] | None = None,
                command: str = "this command") -> Any:
    """The strategy's default Params for ``problem`` with the overrides ``text``
    (``"q0=0.9,use_chaos=true"``, the ``params`` setting of every search command), checked:
    unknown fields, values outside their ranges and fields the switches leave unused are one
    ConfigError line each (``fixed``, ``command``: see :func:`refuse_inactive`)."""
    overrides = parse_overrides(text)
    params = params_with(strategy.default_params(problem), overrides, where)
    strategy.check_params(params, where)
    refuse_inactive(strategy, params, overrides, where, fixed, command)
    return params


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
        except TypeError as err:  # e.g. a Settings class without defaults for some field
            raise ConfigError(f"{where}{err}") from None
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
    info = {"kind": kind, "settings": settings_dict(settings), "checkpoint_every": every,
            "command": command_line(kind, settings, directory, every)}
    return Checkpointing(directory, every=every, run_info=info)


def command_line(kind: str, settings: Any, directory: str | Path | None = None,
                 every: int | None = None) -> str:
    """The ``eaco`` command that starts this run (the settings that differ from their
    defaults, as the flags :mod:`eaco_jax.cli.runs` generates): printed when a checkpoint
    folder cannot be resumed, so the run can be started again."""
    import shlex

    words, flags = ["eaco", kind], []
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        if f.metadata.get("positional"):
            words.append(shlex.quote(str(value)))
        elif value != f.default and value is not None:
            flag = "--" + ("" if value is not False else "no-") + f.name.replace("_", "-")
            flags += [flag] if isinstance(value, bool) else [flag, shlex.quote(str(value))]
    if directory is not None:
        flags += ["--checkpoint-dir", shlex.quote(str(Path(directory).absolute()))]
    if every is not None:
        flags += ["--checkpoint-every", str(every)]
    return " ".join(words + flags)


def check_out(out: str | None, files: tuple[str, ...] = ()) -> None:
    """Refuse an output folder that is a file or not writable, before anything runs."""
    if out is None:
        return
    from eaco_jax.errors import ConfigError

    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"--out {folder} is an existing file; give a folder")
    for name in files:
        if (folder / name).is_dir():
            raise ConfigError(f"--out {folder}: {folder / name} is a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / ".write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as err:
        raise ConfigError(f"--out {folder} is not writable ({err.strerror}); choose another "
                          "folder") from None


def budget_of(s: Any, iterations: int | None, default: dict[str, int] | None = None,
              chunk: int | None = None) -> dict[str, Any]:
    """The budget keywords of ``minimize`` from a Settings with ``max_evaluations`` /
    ``max_seconds`` fields: ``max_evaluations`` (if set) replaces ``iterations``.

    Neither given: with ``max_seconds``, no iteration cap (time ends the run, checked every
    ``chunk`` iterations: default a twentieth of ``default``'s iterations, as a run of the
    default budget is chunked); without it, ``default`` (the kind's default budget, e.g.
    ``{"iterations": 300}``).
    """
    from eaco_jax.driver.rows import UNCAPPED, default_chunk

    budget: dict[str, Any] = {}
    max_evals = getattr(s, "max_evaluations", None)
    max_seconds = getattr(s, "max_seconds", None)
    if max_evals is not None:
        budget["max_evaluations"] = int(max_evals)
    elif iterations is not None:
        budget["iterations"] = int(iterations)
    elif max_seconds is not None:
        budget["iterations"] = UNCAPPED
        per = (default or {}).get("iterations", 100)
        budget["chunk_size"] = chunk if chunk is not None else default_chunk(per, None)
    elif default:
        budget.update(default)
    if max_seconds is not None:
        budget["max_seconds"] = float(max_seconds)
    return budget


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
