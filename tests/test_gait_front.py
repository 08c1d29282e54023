"""``eaco gait-front``: the Pareto front of walking speed against endurance or electrical CoT
from the command line (``eaco_jax/runs/gait_front.py``)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.problems.gait_mo import make_gait_mo_problem
from eaco_jax.runs import gait_front

RUNNER = CliRunner()


def _cli(*args: str):
    res = RUNNER.invoke(app, ["--no-compile-cache", *args])
    lines = [ln for ln in res.output.strip().splitlines() if ln.strip()]
    return res.exit_code, (lines[-1] if lines else "")


def test_a_short_run_writes_the_front_files_and_says_why_the_front_is_empty(tmp_path):
    """Random gaits in two randomised worlds for one second all break a constraint: the
    record has an empty front, the least-violating gait and its violation, and the files."""
    out = tmp_path / "front"
    code, last = _cli("gait-front", "--backend", "native", "--ants", "4", "--iterations",
                      "2", "--horizon", "1", "--robust", "2", "--out", str(out), "--steer",
                      "--target-noise", "0.0004")
    assert code == 0, last
    assert "no gait met every constraint in 2 worlds (least violation" in last
    rec = json.loads((out / "front.json").read_text())
    assert rec["front_size"] == 0 and rec["front"] == []
    assert rec["steering"]["gain"] == 1.0 and rec["target_noise"] == pytest.approx(0.0004)
    assert rec["least_violation"]["violation"] > 0
    assert set(rec["least_violation"]["params"]) >= {"step_length", "period"}
    assert rec["constraints"] == ["current", "slip", "drift", "falls"]
    assert rec["iterations"] == 2 and rec["evaluations"] == 8
    assert len(rec["history_hypervolume"]) == 2
    for name in ("front.csv", "front.png", "hypervolume.png"):
        assert (out / name).stat().st_size > 0
    with open(out / "front.csv") as fh:
        assert list(csv.reader(fh)) == [["speed_mps", "endurance_min"]]


@pytest.mark.parametrize("second", ["endurance", "cot"])
def test_front_rows_turn_the_minimised_columns_back_into_speed_and_the_second(second):
    problem = make_gait_mo_problem("nao", second, backend="native", horizon=1.0)
    x = np.asarray(problem.lower) + 0.25 * (np.asarray(problem.upper) - np.asarray(problem.lower))
    f = np.array([[-0.3, -12.0 if second == "endurance" else 1.7]])
    rows = gait_front.front_rows(problem, {"x": x[None], "f": f})
    assert rows[0]["speed_mps"] == pytest.approx(0.3)
    if second == "endurance":
        assert rows[0]["endurance_min"] == pytest.approx(12.0)
    else:
        assert rows[0]["electrical_cot"] == pytest.approx(1.7)
    assert rows[0]["params"] == problem.params_dict(x)


def test_the_front_csv_has_one_row_per_gait_with_its_parameters(tmp_path):
    record = {"robot": "nao", "second": "cot", "robust": 4, "front_size": 2,
              "objectives": ["speed [m/s]", "electrical CoT"], "hypervolume_units": "m/s x CoT",
              "history_hypervolume": [0.0, 0.5],
              "front": [{"speed_mps": 0.1, "electrical_cot": 1.0, "params": {"a": 1.0, "b": 2.0}},
                        {"speed_mps": 0.2, "electrical_cot": 2.5, "params": {"a": 3.0, "b": 4.0}}]}
    gait_front.write_outputs(tmp_path, record, {})
    with open(tmp_path / "front.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows == [["speed_mps", "electrical_cot", "a", "b"], ["0.1", "1.0", "1.0", "2.0"],
                    ["0.2", "2.5", "3.0", "4.0"]]
    assert json.loads((tmp_path / "front.json").read_text())["front_size"] == 2
    assert gait_front.summary({**record, "hypervolume": 0.5, "iterations": 2}) == (
        "nao speed x cot: 2 gaits on the front, 0.100-0.200 m/s, hypervolume 0.5 m/s x CoT; "
        "2 iterations")


@pytest.mark.parametrize(("args", "says"), [
    (("--ants", "1"), "ants must be >= 2 (the archive ranks them), got 1; e.g. --ants 32"),
    (("--robust", "-1"), "robust must be >= 0 (0: the nominal world only), got -1"),
    (("--second", "speed"), "second='speed' is not one of endurance, cot"),
    (("--target-noise", "-1"), "target_noise must be a number of radians in [0, 0.1]"),
])
def test_bad_settings_are_one_line(args, says):
    code, last = _cli("gait-front", *args)
    assert code == 2 and last.startswith("error: ") and says in last, last
