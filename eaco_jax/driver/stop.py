"""Stop rules: predicates the driver checks on the host after every compiled chunk.

A stop rule is any callable ``rule(state, progress) -> bool`` (True ends the run). ``state`` is
the colony state (with a leading row axis when several seeds or settings run at once) and
``progress`` a :class:`Progress` record. The iteration budget is not a rule: it fixes the
length of the compiled run and is given to :func:`~eaco_jax.driver.minimize.minimize` as
``iterations`` (or ``max_evaluations``). Rules stop *after* the chunk in which they fire;
``chunk_size`` sets how often they are checked. A rule with ``before_chunk = True`` (a
deadline) is also checked before every chunk and after each compilation, so that a deadline
that passed during setup ends the run before its first iteration.

Built in (also reachable through ``minimize``'s keywords of the same meaning)::

    Target(value)            every row's best cost <= value        (target=)
    Patience(iterations)     every row stagnated this long         (patience=)
    WallTime(seconds)        compute seconds since the start       (max_seconds=)
    Deadline(at)             time.monotonic() reached ``at``       (deadline=)
    Evaluations(n)           every row charged >= n evaluations
    Callback(fn)             fn(state, progress) returned True     (callback=)
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class Progress:
    """Where a run stands after a chunk.

    Attributes:
      iterations: iterations completed (a resumed run counts those before the restart).
      seconds: compute seconds of this process's run so far, compilation excluded.
      compile_seconds: seconds spent compiling so far.
      now: ``time.monotonic()`` when the progress was taken (default: at construction).
    """

    iterations: int
    seconds: float
    compile_seconds: float
    now: float = dataclasses.field(default_factory=time.monotonic)


StopRule = Callable[[Any, Progress], bool]


@dataclasses.dataclass(frozen=True)
class Target:
    """Stop once every row's best cost is at or below ``value``.

    For constrained problems the full-precision feasible objective (``best_f`` where
    ``best_violation <= 0``) is compared, not the float32 ``best_cost``: at |f| ~ 7000 float32
    cannot resolve a 1e-4 target.
    """

    value: float

    def __call__(self, state: Any, progress: Progress) -> bool:
        f = getattr(state, "best_f", None)
        if f is None:
            return bool(np.all(np.asarray(state.best_cost) <= self.value))
        feasible = np.asarray(state.best_violation) <= 0
        return bool(np.all(feasible & (np.asarray(f, np.float64) <= self.value)))


@dataclasses.dataclass(frozen=True)
class Patience:
    """Stop once every row has gone ``iterations`` iterations without improving."""

    iterations: int

    def __call__(self, state: Any, progress: Progress) -> bool:
        return bool(np.all(np.asarray(state.stagnation) >= self.iterations))


@dataclasses.dataclass(frozen=True)
class WallTime:
    """Stop once ``seconds`` of compute (compilation excluded) have passed."""

    seconds: float

    def __call__(self, state: Any, progress: Progress) -> bool:
        return progress.seconds >= self.seconds


@dataclasses.dataclass(frozen=True)
class Deadline:
    """Stop once the wall clock (``time.monotonic()``) reaches ``at``: a budget counted from
    a moment the caller chose (e.g. the program's start, see :func:`process_started_at`), so
    reading the data, compilation and the first tour count against it. Checked before every
    chunk too (``before_chunk``): a deadline that passed during setup runs no iteration."""

    at: float
    before_chunk = True

    def __call__(self, state: Any, progress: Progress) -> bool:
        return progress.now >= self.at


def process_started_at() -> float | None:
    """When this process started, on the ``time.monotonic()`` clock (None where the operating
    system does not say): the start of the ``eaco`` command's call, interpreter start-up and
    imports included. Linux only, to 1/100 s (``/proc/self/stat`` field 22)."""
    try:
        with open("/proc/self/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        ticks = int(fields[19])  # field 22 of the whole line: start time, clock ticks
        hz = os.sysconf("SC_CLK_TCK")  # the kernel's clock ticks per second
        boot_now = time.clock_gettime(time.CLOCK_BOOTTIME)
    except (OSError, IndexError, ValueError, AttributeError):
        return None
    age = boot_now - ticks / hz
    return time.monotonic() - age if math.isfinite(age) and age >= 0 else None


@dataclasses.dataclass(frozen=True)
class Evaluations:
    """Stop once every row has been charged at least ``n`` evaluations."""

    n: int

    def __call__(self, state: Any, progress: Progress) -> bool:
        return bool(np.all(np.asarray(state.evaluations) >= self.n))


@dataclasses.dataclass(frozen=True)
class Callback:
    """Call ``fn(state, progress)`` after every chunk; it ends the run by returning True."""

    fn: Callable[[Any, Progress], Any]

    def __call__(self, state: Any, progress: Progress) -> bool:
        return bool(self.fn(state, progress))
