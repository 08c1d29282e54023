"""Stopping on SIGINT / SIGTERM: the signal handler the run loop installs, the poll that lets a
signal stop a compilation, and the line an interrupted run ends with."""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import numpy as np


class CompileInterrupted(Exception):
    """Raised inside the driver when SIGINT/SIGTERM arrived (turned into :class:`Interrupted`)."""


def polled(fn: Callable[[], Any], interrupted: Callable[[], bool] | None) -> Any:
    """``fn()`` in a worker thread, polled every 0.1 s so a signal can stop the wait."""
    if interrupted is None:
        return fn()
    box: dict[str, Any] = {}
    x64 = bool(jax.config.jax_enable_x64)  # JAX's config scopes are per thread

    def target() -> None:
        try:
            with jax.enable_x64(x64):
                box["value"] = fn()
        except BaseException as err:  # noqa: BLE001 - re-raised in the caller's thread
            box["error"] = err

    worker = threading.Thread(target=target, name="eaco-compile", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(0.1)
        if interrupted():
            raise CompileInterrupted
    if "error" in box:
        raise box["error"]
    return box["value"]


class Signals:
    """SIGINT / SIGTERM set a flag (the driver stops at the next chunk boundary) and say so at
    once, naming the iteration the current chunk ends at (``at``); a second signal exits at
    once. Installed only in the main thread."""

    def __init__(self, newline: bool = False) -> None:
        self.name: str | None = None
        self.at = 0
        self._newline = newline  # a progress bar holds the current line
        self._old: dict[int, Any] = {}
        self._err: int | None = None  # stderr as it was (a save may point fd 2 elsewhere)

    def __enter__(self) -> Signals:
        if threading.current_thread() is not threading.main_thread():
            return self
        sys.stderr.flush()
        self._err = os.dup(2)
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self._old[sig] = signal.signal(sig, self._handle)
            except (ValueError, OSError):  # pragma: no cover - exotic embeddings
                pass
        return self

    def _handle(self, signum: int, frame: Any) -> None:
        if self.name is not None:  # second signal: stop now
            self._say("\ninterrupted again: exiting without saving\n")
            os._exit(130)
        self.name = signal.Signals(signum).name
        self._say(f"{chr(10) if self._newline else ''}{self.name}: stopping after the current "
                  f"chunk (iteration {self.at}); send again to stop now\n")

    def _say(self, text: str) -> None:
        sys.stderr.flush()
        os.write(self._err if self._err is not None else 2, text.encode())

    def __exit__(self, *exc: Any) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        if self._err is not None:
            os.close(self._err)
            self._err = None

    def __call__(self) -> bool:
        return self.name is not None


def interrupt_message(name: str, result: Any, done: int, total: int,
                      checkpointing: Any | None) -> str:
    """The line an interrupted run ends with: where its checkpoint is and how to continue, or
    (without checkpointing) the best so far of ``result``."""
    of = "" if total >= 2**31 - 1 else f" of {total}"  # 2**31 - 1: no cap (rows.UNCAPPED)
    head = f"interrupted ({name}) after {done}{of} iterations"
    if checkpointing is not None and done == 0:
        return f"{head}; nothing to save yet (start the same command again)"
    if checkpointing is not None:
        where = Path(checkpointing.directory)
        info = checkpointing.run_info or {}
        how = (f"eaco resume {where}" if info.get("kind") else
               "call minimize() again with the same Checkpointing")
        return f"{head}; checkpoint saved at step {done} in {where}; continue with: {how}"
    best = np.asarray(result.best_cost, np.float64).reshape(-1)
    shown = ", ".join(f"{b:.6g}" for b in best[:8]) + (", ..." if best.size > 8 else "")
    return f"{head}; best so far: {shown} (no checkpoint: pass --checkpoint-dir to resume)"
