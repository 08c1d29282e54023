"""The ``eaco`` command line. Each module of this package registers its own sub-commands.

A module defines ``register(app: typer.Typer) -> None``; modules are discovered, so adding a
command never means editing this file. The run commands come from :mod:`eaco_jax.runs`
(:mod:`eaco_jax.cli.runs`): the command line parses and prints, the runs do the work.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from typing import Any

import typer
from typer.core import TyperGroup

try:  # typer >= 0.2x carries its own copy of click
    from typer._click import exceptions as click_errors
except ImportError:  # an older typer parses with click itself
    from click import exceptions as click_errors  # type: ignore[no-redef]


class OneLineErrors(TyperGroup):
    """The ``eaco`` group: a usage error of any command (unknown option, missing argument,
    bad value) is one line ``error: ... (see 'eaco CMD --help')`` and exit code 2, as the
    library's user errors are, instead of typer's boxed usage text."""

    def main(self, args: Any = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> Any:
        try:
            rv = super().main(args=args, prog_name=prog_name, complete_var=complete_var,
                              standalone_mode=False, **extra)
        except click_errors.NoArgsIsHelpError as err:  # bare ``eaco``: the help
            if not standalone_mode:
                raise
            typer.echo(err.ctx.get_help())
            sys.exit(err.exit_code)
        except click_errors.ClickException as err:
            if not standalone_mode:
                raise
            typer.echo(f"error: {usage_line(err)}", err=True)
            sys.exit(2)
        except typer.Abort:
            if not standalone_mode:
                raise
            typer.echo("aborted", err=True)
            sys.exit(1)
        if not standalone_mode:
            return rv
        sys.exit(rv if isinstance(rv, int) else 0)


def usage_line(err: click_errors.ClickException) -> str:
    """One line for a command-line usage error, naming the command's ``--help``."""
    text = " ".join(err.format_message().split())
    ctx = getattr(err, "ctx", None)
    if ctx is None:
        return text
    return f"{text} (see '{ctx.command_path} --help')"


app = typer.Typer(
    cls=OneLineErrors,
    name="eaco",
    help="Enhanced elitist-mutated ant colony optimisation: TSP, constrained problems, gaits.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

def _version(value: bool) -> None:
    if value:
        from eaco_jax._version import __version__

        typer.echo(f"eaco_jax {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="print the version and exit"),
    compile_cache: bool = typer.Option(
        True, "--compile-cache/--no-compile-cache",
        help="JAX's persistent compilation cache (a repeated or resumed run does not compile "
             "again); folder: $EACO_COMPILE_CACHE or ~/.cache/eaco_jax/jax"),
) -> None:
    """Enhanced elitist-mutated ant colony optimisation: TSP, constrained problems, gaits."""
    if compile_cache:
        from eaco_jax.cli.common import one_line_warnings

        one_line_warnings()  # the cache's own warning, before any command sets it
        enable_compile_cache()


def enable_compile_cache(folder: str | None = None) -> str:
    """Turn on JAX's persistent compilation cache (every compiled program is kept on disk).

    Returns the folder, or "" with one warning when it cannot be used (a file, unwritable):
    the run goes on without the cache, which costs only compile time."""
    import os
    import warnings
    from pathlib import Path

    import jax

    from_env = not folder and bool(os.environ.get("EACO_COMPILE_CACHE"))
    path = folder or os.environ.get("EACO_COMPILE_CACHE") or str(
        Path.home() / ".cache" / "eaco_jax" / "jax")
    why = ""
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
        if not os.access(path, os.W_OK | os.X_OK):
            why = "is not writable"
    except FileExistsError:
        why = "is a file, not a folder"
    except OSError as err:
        why = f"cannot be created ({err.strerror})"
    if why:
        what, fix = ((f"EACO_COMPILE_CACHE={path}", "point it at a writable folder") if from_env
                     else (path, "set EACO_COMPILE_CACHE to a writable folder"))
        warnings.warn(f"compile cache off: {what} {why}; {fix}, or pass --no-compile-cache",
                      stacklevel=2)
        return ""
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path


for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name.startswith("_") or _info.name == "common":
        continue
    importlib.import_module(f"{__name__}.{_info.name}").register(app)


def main() -> None:
    """The ``eaco`` entry point: the app, with a bare Ctrl-C answered by one line."""
    import os
    import signal

    if getattr(signal.getsignal(signal.SIGINT), "__name__", "") == "_interrupted_while_starting":
        signal.signal(signal.SIGINT, signal.default_int_handler)  # started: Ctrl-C as usual
    try:
        app()
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        sys.stderr.flush()
        os._exit(130)
