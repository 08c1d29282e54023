"""What every ``eaco`` command shares: one-line errors for user errors, the JSON output line."""

from __future__ import annotations

import functools
import json
import os
import sys
import warnings
from collections.abc import Callable
from typing import Any

import typer

from eaco_jax.errors import Interrupted, UserError
from eaco_jax.outputs import to_jsonable


def _one_line_warning(message: Any, category: type, filename: str, lineno: int,
                      line: str | None = None) -> str:
    return f"warning: {message}\n"


def one_line_warnings() -> None:
    """Print the library's warnings as ``warning: ...`` lines (no file and line)."""
    warnings.formatwarning = _one_line_warning  # type: ignore[assignment]


def emit_json(record: dict[str, Any]) -> None:
    """Print ``record`` as the last stdout line, one JSON object."""
    sys.stdout.write(json.dumps(to_jsonable(record)) + "\n")
    sys.stdout.flush()


def fail(message: str) -> None:
    """One-line error on stderr and exit code 2 (never a traceback for bad input)."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


def guarded(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn the library's user errors (:class:`~eaco_jax.errors.UserError`) into one line.

    Anything else is a bug and keeps its traceback.
    """

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        one_line_warnings()
        try:
            return fn(*args, **kwargs)
        except UserError as err:
            fail(str(err))
        except KeyboardInterrupt as err:  # Interrupted (with what to do next) or a bare Ctrl-C
            text = str(err) if isinstance(err, Interrupted) else "interrupted"
            sys.stdout.flush()
            sys.stderr.write(f"{text}\n")
            sys.stderr.flush()
            os._exit(130)  # a compilation may still run in a worker thread: do not wait for it

    return wrapper
