"""``eaco constrained``: JSON record, output folder, clean errors."""

import json

import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.runs import constrained, kinds


def test_cli_errors_are_one_line():
    runner = CliRunner()
    res = runner.invoke(app, ["constrained", "g99", "--json"])
    assert res.exit_code == 2
    assert "unknown CEC2006 problem" in res.output
    res = runner.invoke(app, ["constrained", "g11", "--method", "lagrange", "--json"])
    assert res.exit_code == 2
    assert "method='lagrange' is not one of epsilon, deb, penalty" in res.output


def test_cli_json_line_and_outputs(tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["constrained", "g11", "--json", "--seed", "1",
                              "--max-evaluations", "2000", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    rec = json.loads(res.output.strip().splitlines()[-1])
    for key in ("problem", "x", "f", "violation", "feasible", "evaluations",
                "evaluations_to_target", "f_star"):
        assert key in rec
    assert rec["problem"] == "g11" and rec["f_star"] == pytest.approx(0.7499)
    assert rec["feasible"] and rec["f"] - rec["f_star"] <= 1e-4
    assert 0 < rec["evaluations_to_target"] <= rec["evaluations"]
    saved = json.loads((tmp_path / "result.json").read_text())
    assert saved["f"] == pytest.approx(rec["f"])
    assert (tmp_path / "convergence.png").stat().st_size > 0
    assert kinds()["constrained"].run is constrained.run
