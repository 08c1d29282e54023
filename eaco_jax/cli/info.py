"""``eaco info``: versions and devices, for bug reports (``--json`` for tools)."""

from __future__ import annotations

from typing import Annotated

import typer


def info_record() -> dict:
    """Package, JAX, MuJoCo versions, devices, and the persistent compilation cache folder."""
    import platform

    import jax

    import eaco_jax

    try:
        import mujoco

        mujoco_version = mujoco.__version__
    except ImportError:  # pragma: no cover - a dependency, but report rather than crash
        mujoco_version = None
    return {
        "eaco_jax": eaco_jax.__version__,
        "python": platform.python_version(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "devices": [str(d) for d in jax.devices()],
        "mujoco": mujoco_version,
        "compilation_cache": jax.config.jax_compilation_cache_dir,
    }


def register(app: typer.Typer) -> None:
    @app.command()
    def info(
        json_out: Annotated[bool, typer.Option("--json", help="print one JSON record")] = False,
    ) -> None:
        """Print package, JAX, MuJoCo versions and the devices JAX sees."""
        record = info_record()
        if json_out:
            from eaco_jax.cli.common import emit_json

            emit_json(record)
            return
        for key, value in record.items():
            typer.echo(f"{key}: {value}")
