"""Import ``mujoco.mjx`` without its "Failed to import warp" lines.

``mujoco.mjx`` tries the optional Warp backend at import and prints ``Failed to import warp: No
module named 'warp'`` (and the same for ``mujoco_warp``) on every machine without it, which is
every user of the JAX backend. :func:`quiet_mjx` drops exactly those lines (warp is simply not
installed) and passes any other output through, e.g. a Warp install that fails to load.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
from types import ModuleType

_NOT_INSTALLED = re.compile(
    r"^Failed to import (?:mujoco_)?warp: No module named '(?:warp|mujoco_warp)[\w.]*'$")


def drop_warp_notes(text: str) -> str:
    """``text`` without the lines saying that (mujoco_)warp is not installed."""
    return "".join(line for line in text.splitlines(keepends=True)
                   if not _NOT_INSTALLED.match(line.rstrip("\n")))


def quiet_mjx() -> ModuleType:
    """``mujoco.mjx``, imported with the not-installed Warp notes removed from stdout."""
    if "mujoco.mjx" in sys.modules:
        return sys.modules["mujoco.mjx"]
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            from mujoco import mjx
    finally:
        sys.stdout.write(drop_warp_notes(buf.getvalue()))
    if "warp" in sys.modules:
        silence_warp(sys.modules["warp"])
    return mjx


def silence_warp(warp: ModuleType) -> None:
    """No greeting and no per-kernel "Module ... load" lines from Warp on stdout, where they
    would land inside a ``--json`` record: older releases read ``config.quiet``, newer ones
    (1.19 here) ``config.log_level``, which keeps warnings and errors."""
    warp.config.quiet = True
    level = getattr(warp, "LOG_WARNING", None)
    if level is not None and hasattr(warp.config, "log_level"):
        warp.config.log_level = level


def warp_usable() -> bool:
    """Whether MJX's Warp implementation can run here: warp-lang imports and JAX's default
    device is a CUDA GPU (MuJoCo Warp has no CPU path)."""
    import jax

    if jax.default_backend() != "gpu":
        return False
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import warp

            silence_warp(warp)
            from mujoco.mjx.third_party import mujoco_warp  # noqa: F401
    except Exception:  # noqa: BLE001 - any failure to load means "not usable"
        return False
    return True
