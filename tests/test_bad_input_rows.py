"""Rows of docs/bad_inputs.md that no behaviour test held: each message, from the route the row
names (the command line, a sweep plan, the API)."""

from __future__ import annotations

import math
import warnings

import pytest
from typer.testing import CliRunner

import eaco_jax as ea
from eaco_jax.cli import app
from eaco_jax.driver.interrupt import interrupt_message
from eaco_jax.driver.minimize import Checkpointing
from eaco_jax.strategies import GraphEACO

RUNNER = CliRunner()


def _cli(*args: str):
    res = RUNNER.invoke(app, ["--no-compile-cache", *args])
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    return res.exit_code, (lines[-1] if lines else "")


@pytest.mark.parametrize(("args", "says"), [
    (("tsp", "burma14", "--params", "q0=abc"), "q0='abc' is not a number or true/false"),
    (("tsp", "burma14", "--max-seconds", "-1"), "max_seconds must be > 0, got -1.0"),
    (("tsp", "burma14", "--checkpoint-every", "5"), "--checkpoint-every needs --checkpoint-dir"),
    (("gait-eval", "experiments/results/nao_best_gait.json", "--stream", "validation"),
     "stream='validation' is not one of test, selection, optimisation"),
])
def test_command_line_refusals_are_one_line(args, says):
    code, last = _cli(*args)
    assert code == 2 and last.startswith("error: ") and says in last, last


def test_sweep_seed_outside_the_key_range_is_refused():
    from eaco_jax.sweep.local import plan

    spec = {"command": "tsp", "args": {"instance": "burma14", "ants": 4, "iterations": 2,
                                       "local_search": "none"}, "seeds": [-1]}
    with pytest.raises(ea.ConfigError, match=r"seeds: -1 is outside the range 0\.\.4294967295"):
        plan(spec)


@pytest.mark.parametrize(("kwargs", "says"), [
    ({"chunk_size": 0}, "chunk_size=0 is outside its range"),
    ({"iterations": 0}, "iterations=0 is outside its range"),
    ({"target": math.nan}, "target must be a finite number, got nan"),
    ({"precision": "half"}, "precision='half' is not one of auto, float32, float64"),
])
def test_minimize_arguments_are_checked_before_a_run(kwargs, says):
    burma = ea.problems.get("burma14")
    with pytest.raises(ea.ConfigError, match=says.replace("(", r"\(")):
        ea.minimize(burma, GraphEACO(num_ants=4, local_search="none"), **kwargs)


def test_a_colony_whose_iteration_is_large_warns_before_it_runs():
    from eaco_jax.driver.memory import check_state_memory
    from eaco_jax.runs import tsp as run_tsp

    built = run_tsp.build(run_tsp.TspSettings(instance="pr1002", ants=200000))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_state_memory(built.strategy, built.problem, 1, built.params)
    text = " ".join(str(w.message) for w in caught)
    assert "needs ~" in text and "GiB per iteration" in text and "expect slow" in text, text


def test_constrained_must_be_a_boolean():
    from eaco_jax.problems.gait import make_gait_problem

    with pytest.raises(ea.ProblemError, match="constrained must be True or False, got 'yes'"):
        make_gait_problem("nao", backend="native", constrained="yes")


class _Result:
    best_cost = [426.0, 430.0]


def test_interrupt_lines_say_what_was_kept(tmp_path):
    assert interrupt_message("SIGINT", _Result(), 0, 3000, Checkpointing(tmp_path)).endswith(
        "after 0 of 3000 iterations; nothing to save yet (start the same command again)")
    line = interrupt_message("SIGINT", _Result(), 7, 3000, None)
    assert line == ("interrupted (SIGINT) after 7 of 3000 iterations; best so far: 426, 430 "
                    "(no checkpoint: pass --checkpoint-dir to resume)")
