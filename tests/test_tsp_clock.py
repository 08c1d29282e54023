"""``eaco tsp --clock call``: a time budget counted from the call (issue 33), beside the run
clock's compute seconds; the deadline stop rule it rests on."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from eaco_jax.driver.minimize import minimize
from eaco_jax.driver.rows import initial_state
from eaco_jax.driver.stop import Deadline, Progress, process_started_at
from eaco_jax.driver.stopping import StopReason
from eaco_jax.errors import ConfigError
from eaco_jax.runs.tsp import TspSettings, build, run

#: a small colony on eil51: compiles in a few seconds on a CPU
SMALL = dict(instance="eil51", ants=8, local_search="none", crossover="none",
             mutation="none", seed=3)
#: the same on the sparse path, whose colony starts from a first tour (2-opt on the Hilbert order)
SPARSE = {**SMALL, "sparse": "on", "local_search": "2opt"}
TIMING = ("clock", "from", "budget_seconds", "startup_seconds", "setup_seconds",
          "compile_seconds", "loop_seconds", "total_seconds", "setup_parts")


def test_deadline_rule_reads_the_progress_clock():
    rule = Deadline(100.0)
    assert not rule(None, Progress(5, 1.0, 0.0, now=99.9))
    assert rule(None, Progress(5, 1.0, 0.0, now=100.0))
    assert Progress(0, 0.0, 0.0).now <= time.monotonic()  # taken at construction


def test_a_deadline_is_checked_before_chunks_and_names_the_setup():
    stop = StopReason([("deadline", Deadline(10.0))], 100, exhausted=lambda s: False,
                      interrupted=lambda: False)
    assert stop.before_chunk(None, 0, Progress(0, 0.0, 0.0, now=9.0)) is None
    assert stop.before_chunk(None, 0, Progress(0, 0.0, 0.0, now=10.0)) == "deadline_in_setup"
    assert stop.after_chunk(None, Progress(5, 1.0, 0.0, now=9.5)) is None
    assert stop.before_chunk(None, 5, Progress(5, 1.0, 0.0, now=10.5)) == "deadline"
    assert stop.after_chunk(None, Progress(10, 2.0, 0.0, now=10.5)) == "deadline"
    # a rule without before_chunk is not asked before a chunk
    late = StopReason([("x", lambda s, p: True)], 100, exhausted=lambda s: False,
                      interrupted=lambda: False)
    assert late.before_chunk(None, 0, Progress(0, 0.0, 0.0)) is None


def test_a_passed_deadline_returns_the_first_tour():
    """The call began 60 s ago (a deterministic stand-in for a slow setup): the run ends
    before its first iteration with the initial state's best tour, while the same budget on
    the run clock searches."""
    s = TspSettings(**SPARSE, max_seconds=1.0, clock="call")
    rec = run(s, started_at=time.monotonic() - 60.0)
    assert rec["stop_reason"] == "deadline_in_setup"
    assert rec["iterations"] == 0 and rec["history_best"] == []
    built = build(s)
    first = initial_state(built.strategy, built.problem, [s.seed], built.params)
    assert rec["tour_from"] == "first tour"  # the Hilbert order after local search
    assert rec["tour"] == np.asarray(first.first_tour).reshape(-1).tolist()
    assert rec["best_length"] == int(built.problem.exact_length(np.asarray(rec["tour"])))
    assert rec["best_length"] < built.problem.exact_length(np.arange(built.problem.n))
    t = rec["timing"]
    assert tuple(t) == TIMING
    assert t["clock"] == "call" and t["from"] == "started_at" and t["budget_seconds"] == 1.0
    assert t["loop_seconds"] == 0.0 and t["startup_seconds"] >= 60.0
    assert t["total_seconds"] >= 60.0

    on_run = run(TspSettings(**SPARSE, max_seconds=1.0), started_at=time.monotonic() - 60.0)
    assert on_run["stop_reason"] == "max_seconds" and on_run["iterations"] > 0
    assert on_run["tour_from"] == "search"
    assert on_run["best_length"] <= rec["best_length"]
    r = on_run["timing"]
    assert r["clock"] == "run" and r["loop_seconds"] >= 1.0 and r["total_seconds"] >= 61.0
    assert math.isclose(r["loop_seconds"], on_run["seconds"] - on_run["compile_seconds"])
    parts = sum(r[k] for k in ("startup_seconds", "setup_seconds", "compile_seconds",
                               "loop_seconds"))
    assert math.isclose(parts, r["total_seconds"], rel_tol=1e-9)
    # the parts of setup timed apart lie inside it
    assert set(r["setup_parts"]) == {"backend_seconds", "read_seconds",
                                     "between_chunks_seconds"}
    assert min(r["setup_parts"].values()) >= 0
    assert r["setup_parts"]["read_seconds"] > 0  # eil51 is read and its lists built
    assert sum(r["setup_parts"].values()) <= r["setup_seconds"]
    # one-iteration chunks: the host reads each one's history while the device waits
    assert r["setup_parts"]["between_chunks_seconds"] > 0

    # the chunk is compiled now: a budget from the call that outlasts the setup searches
    t0 = time.monotonic()
    live = run(TspSettings(**SPARSE, max_seconds=1.5, clock="call"), started_at=t0)
    assert live["stop_reason"] == "deadline" and live["iterations"] > 0
    assert live["timing"]["total_seconds"] >= 1.5
    assert time.monotonic() - t0 >= 1.5


def test_the_dense_path_returns_file_order_when_no_iteration_ran():
    """The dense path has no tour before its first iteration: the record says the returned
    order is the file's, not a search result."""
    rec = run(TspSettings(**SMALL, max_seconds=1.0, clock="call"),
              started_at=time.monotonic() - 60.0)
    assert rec["stop_reason"] == "deadline_in_setup" and rec["tour_from"] == "file order"
    assert rec["tour"] == list(range(51))


def test_minimize_deadline_keyword():
    built = build(TspSettings(**SMALL))
    res = minimize(built.problem, built.strategy, seed=0, iterations=50,
                   deadline=time.monotonic() - 1.0)
    assert res.stop_reason == "deadline_in_setup" and res.iterations == 0
    res = minimize(built.problem, built.strategy, seed=0, iterations=5,
                   deadline=time.monotonic() + 3600.0)
    assert res.stop_reason == "iterations" and res.iterations == 5


class PassesWhileCompiling:
    """A deadline-like rule that fires from its second check on: the loop's first check
    passes, and the one after the chunk's compilation sees the deadline gone."""

    before_chunk = True

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, state, progress) -> bool:
        self.calls += 1
        return self.calls >= 2


def test_a_deadline_that_passes_while_compiling_runs_no_chunk():
    from eaco_jax.driver.programs import clear_compiled

    built = build(TspSettings(**SMALL))
    clear_compiled()  # the chunk compiles (or loads) now, so the check after it runs
    res = minimize(built.problem, built.strategy, seed=0, iterations=5,
                   stop=PassesWhileCompiling())
    assert res.stop_reason == "PassesWhileCompiling_in_setup" and res.iterations == 0


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), "soon", True])
def test_bad_deadlines_are_refused(bad):
    built = build(TspSettings(**SMALL))
    with pytest.raises(ConfigError, match=r"deadline must be a time.monotonic\(\) value"):
        minimize(built.problem, built.strategy, seed=0, iterations=5, deadline=bad)


@pytest.mark.parametrize("bad", [float("nan"), "now", True, "future"])
def test_bad_started_at_is_refused(bad):
    # the future start is taken here, not at collection: xdist's workers must collect the same ids
    bad = time.monotonic() + 3600.0 if bad == "future" else bad
    with pytest.raises(ConfigError, match=r"started_at must be a time.monotonic\(\) value "
                                          r"taken before the call"):  # (2 iterations if not)
        run(TspSettings(**SMALL, iterations=2, max_seconds=1.0, clock="call"), started_at=bad)


@pytest.mark.parametrize("kw, message", [
    (dict(clock="call"), r"clock='call' counts the --max-seconds budget from the call; "
                         r"give --max-seconds S"),
    (dict(clock="wall", max_seconds=1.0), r"clock='wall' is not one of run, call"),
    (dict(clock="call", max_seconds=float("nan")), r"max_seconds=nan must be a finite number"),
    (dict(clock="call", max_seconds=0.0), r"max_seconds must be > 0, got 0.0"),
    (dict(clock="call", max_seconds="18"), r"max_seconds='18' must be a finite number"),
])
def test_bad_clock_settings_are_one_line(kw, message):
    with pytest.raises(ConfigError, match=message) as err:
        TspSettings(instance="eil51", **kw)
    assert "\n" not in str(err.value)


def test_process_start_is_before_now():
    started = process_started_at()
    if started is None:
        pytest.skip("this system does not report a process start")
    assert started <= time.monotonic()


def _cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    return subprocess.run([sys.executable, "-m", "eaco_jax", "tsp", *args], env=env,
                          capture_output=True, text=True, timeout=300)


def test_the_command_counts_from_its_process_start():
    """A budget shorter than the command's start-up (interpreter and imports, a second or
    so): the run ends in setup, and the record counts the start-up in the total."""
    if process_started_at() is None:
        pytest.skip("this system does not report a process start")
    done = _cli("eil51", "--ants", "8", "--max-seconds", "0.05", "--clock", "call", "--json")
    assert done.returncode == 0, done.stderr
    rec = json.loads(done.stdout[done.stdout.index("{"):])
    t = rec["timing"]
    assert rec["stop_reason"] == "deadline_in_setup" and rec["iterations"] == 0
    assert t["from"] == "process start" and t["clock"] == "call"
    assert t["startup_seconds"] > 0.05  # python + jax imports: well over 50 ms
    assert t["total_seconds"] >= t["startup_seconds"]


def test_the_command_refuses_a_call_clock_without_budget_in_one_line():
    done = _cli("eil51", "--clock", "call")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "give --max-seconds S" in lines[0]
