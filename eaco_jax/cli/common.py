"""What every ``eaco`` command shares: JSON output, clean errors, output folders."""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import typer


def to_jsonable(value: Any) -> Any:
    """numpy / jax values -> plain JSON types (non-finite floats become null)."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if hasattr(value, "shape") and hasattr(value, "dtype"):
        value = np.asarray(value)
        return to_jsonable(value.tolist()) if value.ndim else to_jsonable(value.item())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, np.generic):
        return to_jsonable(value.item())
    return value


def emit_json(record: dict[str, Any]) -> None:
    """Print ``record`` as the last stdout line, one JSON object."""
    sys.stdout.write(json.dumps(to_jsonable(record)) + "\n")
    sys.stdout.flush()


def write_json(path: Path, record: dict[str, Any]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(to_jsonable(record), indent=2) + "\n")
    return path


def fail(message: str) -> None:
    """One-line error on stderr and exit code 2 (never a traceback for bad input)."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=2)


def guarded(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn the library's input errors into :func:`fail` one-liners."""
    import functools

    from eaco_jax.problems.base import ProblemError

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except (ProblemError, ValueError, FileNotFoundError, KeyError, TypeError) as err:
            msg = err.args[0] if isinstance(err, KeyError) and err.args else err
            fail(str(msg))

    return wrapper


# --------------------------------------------------------------------------- run registry
#: name -> function(**args) -> JSON record. Every run command (tsp, constrained, gait) registers
#: its plain-Python runner here so `eaco resume DIR` can re-run a checkpointed command from the
#: arguments stored in the checkpoint (``run_info={"command": name, "args": args}``).
RUNNERS: dict[str, Callable[..., dict[str, Any]]] = {}


def register_runner(name: str, fn: Callable[..., dict[str, Any]]) -> Callable[..., dict[str, Any]]:
    RUNNERS[name] = fn
    return fn
