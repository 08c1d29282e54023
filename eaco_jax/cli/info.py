"""``eaco info``: versions and devices, for bug reports."""

from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def info() -> None:
        """Print package, JAX, MuJoCo versions and the devices JAX sees."""
        import jax
        import mujoco

        import eaco_jax

        typer.echo(f"eaco_jax {eaco_jax.__version__}")
        typer.echo(f"jax {jax.__version__}  devices: {jax.devices()}")
        typer.echo(f"mujoco {mujoco.__version__}")
