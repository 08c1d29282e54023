"""The run loop's stop reason is decided in one place (``driver/stopping.py::StopReason``)."""

from __future__ import annotations

import inspect
import re

from eaco_jax.driver import minimize as driver
from eaco_jax.driver.stop import Progress
from eaco_jax.driver.stopping import StopReason


def _reason(total=10, fired=(), exhausted=False, interrupted=False):
    called = []

    def rule(name, fires):
        def check(state, progress):
            called.append(name)
            return fires
        return name, check

    rules = [rule("a", "a" in fired), rule("b", "b" in fired)]
    stop = StopReason(rules, total, exhausted=lambda s: exhausted,
                      interrupted=lambda: interrupted)
    return stop, called


def test_after_a_chunk_rules_then_budget_then_signal_then_iterations():
    stop, called = _reason(fired=("b",), exhausted=True, interrupted=True)
    assert stop.after_chunk(None, Progress(10, 0.0, 0.0)) == "b"
    assert called == ["a", "b"]  # every rule sees every chunk
    stop, called = _reason(fired=("a", "b"))
    assert stop.after_chunk(None, Progress(3, 0.0, 0.0)) == "a" and called == ["a", "b"]
    stop, _ = _reason(exhausted=True, interrupted=True)
    assert stop.after_chunk(None, Progress(10, 0.0, 0.0)) == "max_evaluations"
    stop, _ = _reason(interrupted=True)
    assert stop.after_chunk(None, Progress(10, 0.0, 0.0)) == "interrupted"
    stop, _ = _reason()
    assert stop.after_chunk(None, Progress(10, 0.0, 0.0)) == "iterations"
    assert stop.after_chunk(None, Progress(9, 0.0, 0.0)) is None


def test_before_a_chunk_the_spent_budget_first_and_no_rule():
    stop, called = _reason(fired=("a",), exhausted=True, interrupted=True)
    assert stop.before_chunk(None, 10) == "iterations"
    assert stop.before_chunk(None, 4) == "max_evaluations" and called == []
    stop, _ = _reason(interrupted=True)
    assert stop.before_chunk(None, 4) == "interrupted"
    stop, _ = _reason()
    assert stop.before_chunk(None, 4) is None


def test_the_loop_sets_no_stop_reason_of_its_own():
    source = inspect.getsource(driver.run)
    assert "stopping.before_chunk(" in source and "stopping.after_chunk(" in source
    assert not re.search(r"reason\s*=\s*[\"']", source)
