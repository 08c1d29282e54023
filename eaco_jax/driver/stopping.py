"""Why a run stops: the named rules of :func:`~eaco_jax.driver.minimize.minimize`'s keywords,
the evaluation cap, and :class:`StopReason`, the one place the run loop's stop reason is
decided."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from eaco_jax.driver.rows import count
from eaco_jax.driver.stop import (
    Callback,
    Deadline,
    Patience,
    Progress,
    StopRule,
    Target,
    WallTime,
)
from eaco_jax.errors import ConfigError
from eaco_jax.strategies.base import State, Strategy


def stop_rules(
    target: float | None = None,
    patience: int | None = None,
    max_seconds: float | None = None,
    callback: Callable[[Any, Progress], Any] | None = None,
    stop: StopRule | Sequence[StopRule] | None = None,
    deadline: float | None = None,
) -> list[tuple[str, StopRule]]:
    """The named stop rules of :func:`minimize`'s keywords."""
    rules: list[tuple[str, StopRule]] = []
    if target is not None:
        if not math.isfinite(float(target)):
            raise ConfigError(f"target must be a finite number, got {target!r}")
        rules.append(("target", Target(float(target))))
    if patience is not None:
        rules.append(("patience", Patience(count("patience", patience))))
    if max_seconds is not None:
        if not (isinstance(max_seconds, int | float) and max_seconds > 0
                and math.isfinite(max_seconds)):
            raise ConfigError(f"max_seconds must be a number > 0, got {max_seconds!r}")
        rules.append(("max_seconds", WallTime(float(max_seconds))))
    if deadline is not None:
        if not (isinstance(deadline, int | float) and not isinstance(deadline, bool)
                and math.isfinite(deadline)):
            raise ConfigError("deadline must be a time.monotonic() value (e.g. "
                              f"time.monotonic() + seconds), got {deadline!r}")
        rules.append(("deadline", Deadline(float(deadline))))
    if callback is not None:
        rules.append(("callback", Callback(callback)))
    if stop is not None:
        for r in ([stop] if callable(stop) else list(stop)):
            rules.append((getattr(r, "__name__", type(r).__name__), r))
    return rules


def exhausted(strategy: Strategy, problem: Any, state: State, budget: int | None) -> bool:
    """Whether no row can start another iteration within ``budget``."""
    if budget is None:
        return False
    charged = np.asarray(state.evaluations, np.int64)
    return bool(np.all(charged + strategy.max_charge(problem) > budget))


class StopReason:
    """The run loop asks it before every chunk and after it; None means go on. The reasons,
    in the order they are checked:

    * after a chunk, the name of the first stop rule that fired (every rule is called on
      every chunk, so callbacks see each one); before a chunk, the first rule with
      ``before_chunk = True`` (a deadline) that fired, as ``"<name>_in_setup"`` when no chunk
      has run yet in this process (the result is then the initial state's best);
    * ``"max_evaluations"``: no row can start another iteration within the cap;
    * ``"interrupted"``: SIGINT / SIGTERM arrived (``interrupted()`` says so);
    * ``"iterations"``: the iteration budget is spent (checked first before a chunk).
    """

    def __init__(self, rules: Sequence[tuple[str, StopRule]], total: int,
                 exhausted: Callable[[State], bool], interrupted: Callable[[], bool]) -> None:
        self.rules = list(rules)
        self.total = total
        self.exhausted = exhausted
        self.interrupted = interrupted
        self.chunks = 0  # chunks run in this process

    def before_chunk(self, state: State, done: int,
                     progress: Progress | None = None) -> str | None:
        """Why not to start another chunk after ``done`` iterations, or None. ``progress``
        (default: ``done`` iterations, now) is what the deadline-like rules see."""
        if done >= self.total:
            return "iterations"
        early = [(name, rule) for name, rule in self.rules
                 if getattr(rule, "before_chunk", False)]
        if early:
            progress = Progress(done, 0.0, 0.0) if progress is None else progress
            fired = [name for name, rule in early if rule(state, progress)]
            if fired:
                return fired[0] if self.chunks else f"{fired[0]}_in_setup"
        return self._budget_or_signal(state)

    def after_chunk(self, state: State, progress: Progress) -> str | None:
        """Why to stop after the chunk that brought the run to ``progress``, or None."""
        self.chunks += 1
        fired = [name for name, rule in self.rules if rule(state, progress)]
        if fired:
            return fired[0]
        reason = self._budget_or_signal(state)
        if reason is None and progress.iterations >= self.total:
            return "iterations"
        return reason

    def _budget_or_signal(self, state: State) -> str | None:
        if self.exhausted(state):
            return "max_evaluations"
        return "interrupted" if self.interrupted() else None
