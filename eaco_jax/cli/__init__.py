"""The ``eaco`` command line. Each module of this package registers its own sub-commands.

A module defines ``register(app: typer.Typer) -> None``; modules are discovered, so adding a
command never means editing this file. The run commands come from :mod:`eaco_jax.runs`
(:mod:`eaco_jax.cli.runs`): the command line parses and prints, the runs do the work.
"""

from __future__ import annotations

import importlib
import pkgutil

import typer

app = typer.Typer(
    name="eaco",
    help="Enhanced elitist-mutated ant colony optimisation: TSP, constrained problems, gaits.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name.startswith("_") or _info.name == "common":
        continue
    importlib.import_module(f"{__name__}.{_info.name}").register(app)
