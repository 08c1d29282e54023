"""``eaco gait`` / ``eaco gait-eval``: real physics on short horizons, outputs, round trip, errors.

One short native optimisation (4 ants, 2 iterations, 0.5 s) is shared by the CI tests; the MJX
and warm-start variants are slow (each compiles the colony loop again).
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.gait.robot import load_robot
from eaco_jax.gait.walk_engine import PARAM_NAMES
from eaco_jax.runs import kinds

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
RECORD_KEYS = ("speed_mps", "distance_m", "fell", "drift_deg", "fitness", "params", "robot",
               "backend", "horizon", "iterations", "evaluations", "seconds", "out")


def last_json(stdout: str) -> dict:
    return json.loads(stdout.strip().splitlines()[-1])


def invoke(args: list[str]):
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, (res.output, res.exception)
    return res


@pytest.fixture(scope="module")
def native_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("gait") / "run"
    res = invoke(["gait", "--robot", "nao", "--backend", "native", "--ants", "4",
                  "--iterations", "2", "--horizon", "0.5", "--seed", "1", "--json",
                  "--out", str(out)])
    return res, out, last_json(res.stdout)


def test_gait_json_record(native_run):
    _, out, rec = native_run
    for key in RECORD_KEYS:
        assert key in rec, key
    assert rec["robot"] == "nao" and rec["backend"] == "native" and rec["horizon"] == 0.5
    assert rec["iterations"] == 2 and rec["out"] == str(out)
    # 2 colonies of 4 (the initial archive is not evaluated)
    assert rec["evaluations"] == 2 * 4
    assert list(rec["params"]) == list(PARAM_NAMES) and len(rec["vector"]) == len(PARAM_NAMES)
    assert isinstance(rec["fell"], bool)
    assert rec["fitness"] >= 0 and np.isfinite(rec["speed_mps"])
    # the re-simulated best reproduces the colony's score (native physics is deterministic)
    assert rec["fitness"] == pytest.approx(rec["search_fitness"], abs=1e-5)
    assert len(rec["history_best"]) == 2 and rec["history_best"][-1] == pytest.approx(
        rec["search_fitness"], abs=1e-6)
    assert "gait" in kinds()


def test_gait_output_files(native_run):
    res, out, rec = native_run
    stored = json.loads((out / "best_gait.json").read_text())
    for key in ("params", "vector", "robot", "horizon", "direction", "slope", "backend",
                "seed", "iterations", "fitness", "speed_mps", "fell", "drift_deg"):
        assert key in stored, key
    assert stored["vector"] == rec["vector"] and stored["seed"] == 1
    for png in ("convergence.png", "joint_angles.png"):
        assert (out / png).read_bytes()[:8] == PNG_MAGIC, png
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == 2 and float(rows[-1]["best_fitness"]) == pytest.approx(
        rec["search_fitness"], abs=1e-6)
    video = out / "best_gait.mp4"
    if video.exists():
        assert video.stat().st_size > 1000 and rec["files"]["video"] == str(video)
    else:
        assert ("video skipped" in res.stderr or "no video by default" in res.stderr) and (
            rec["files"]["video"] is None)


def test_gait_eval_round_trip(native_run, tmp_path):
    _, out, rec = native_run
    res = invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native", "--json",
                  "--out", str(tmp_path / "eval"), "--no-video"])
    ev = last_json(res.stdout)
    assert ev["robot"] == "nao" and ev["horizon"] == 0.5 and ev["params"] == rec["params"]
    for key in ("fitness", "speed_mps", "distance_m", "drift_deg"):
        assert ev[key] == pytest.approx(rec[key], abs=1e-6), key
    assert ev["fell"] == rec["fell"]
    # energy and gait quality in both records (NAO has a motor datasheet), the same run
    for r in (rec, ev):
        q = r["quality"]
        assert q["mean_power_w"] > 0 and q["peak_power_w"] >= q["mean_power_w"]
        assert 0 < q["peak_speed_frac"] and 0 < q["peak_torque_frac"]
        assert set(q["rms_torque_frac"]) == set(load_robot("nao").joint_names)
        assert isinstance(q["overheating"], list)
    assert ev["quality"]["energy_j"] == pytest.approx(rec["quality"]["energy_j"], rel=1e-6)
    assert (tmp_path / "eval" / "joint_angles.png").read_bytes()[:8] == PNG_MAGIC
    assert not (tmp_path / "eval" / "best_gait.mp4").exists()
    # a longer horizon is a different simulation of the same parameters
    res = invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native",
                  "--horizon", "1.0", "--json"])
    assert last_json(res.stdout)["horizon"] == 1.0


def test_gait_eval_ant_by_name(tmp_path):
    """A second robot through the same command: params given by name, a quadruped gait."""
    from eaco_jax.gait.walk_engine import ANT_LOWER, ANT_PARAM_NAMES, ANT_UPPER

    mid = (ANT_LOWER + ANT_UPPER) / 2
    path = tmp_path / "ant.json"
    path.write_text(json.dumps({"robot": "ant", "horizon": 0.4,
                                "params": dict(zip(ANT_PARAM_NAMES, mid.tolist(), strict=True))}))
    ev = last_json(invoke(["gait-eval", str(path), "--backend", "native", "--json"]).stdout)
    assert ev["robot"] == "ant" and ev["horizon"] == 0.4
    assert list(ev["params"]) == list(ANT_PARAM_NAMES) and np.isfinite(ev["fitness"])


def one_line_error(args: list[str]) -> str:
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, (args, res.output)
    err = res.stderr.strip()
    assert err.startswith("error:") and len(err.splitlines()) == 1, err
    assert "Traceback" not in res.output
    return err


def test_bad_input_is_a_one_line_error(tmp_path):
    assert "unknown robot 'robo'" in one_line_error(["gait", "--robot", "robo", "--json"])
    assert "backend='gpu' is not one of" in one_line_error(["gait", "--backend", "gpu"])
    assert "ants=0 is outside its range 1..2147483647" in one_line_error(["gait", "--ants", "0"])
    assert "does not exist" in one_line_error(["gait-eval", str(tmp_path / "none.json")])
    assert "does not exist" in one_line_error(
        ["gait", "--init", str(tmp_path / "none.json"), "--iterations", "1"])
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert "not valid JSON" in one_line_error(["gait-eval", str(bad)])
    bad.write_text(json.dumps({"robot": "nao", "vector": [0.1, 0.2]}))
    assert "needs 14 parameters" in one_line_error(["gait-eval", str(bad)])
    bad.write_text(json.dumps({"robot": "nao", "params": {"step_length": 0.1}}))
    assert "missing" in one_line_error(["gait-eval", str(bad)])
    bad.write_text(json.dumps({"robot": "nao", "vector": [float("nan")] * 14}))
    assert "finite" in one_line_error(["gait-eval", str(bad)])
    bad.write_text(json.dumps({"robot": "nao", "vector": [50.0] * 14}))
    assert "is outside the walk engine's range" in one_line_error(["gait-eval", str(bad)])
    bad.write_text(json.dumps({"robot": "nao", "vector": [0.0] * 14}))
    assert "backend='cuda' is not one of" in one_line_error(
        ["gait-eval", str(bad), "--backend", "cuda"])
    assert "unknown robot" in one_line_error(["gait-eval", str(bad), "--robot", "robo"])
    bad.write_text(json.dumps([1, 2, 3]))
    assert "'vector'" in one_line_error(["gait-eval", str(bad)])


def test_horizon_past_the_step_clock_is_refused_before_any_simulation(tmp_path):
    """--horizon 1e9 (5e10 control steps) aborted XLA after an int32 truncation warning."""
    from eaco_jax.errors import ProblemError
    from eaco_jax.problems.gait import MAX_CONTROL_STEPS, make_gait_problem

    dt = load_robot("nao").control_dt
    most = int(MAX_CONTROL_STEPS * dt)
    want = f"use a horizon of at most {most} s"
    gait = tmp_path / "g.json"
    gait.write_text(json.dumps({"robot": "nao", "vector": [0.0] * 14}))
    assert want in one_line_error(["gait", "--backend", "native", "--horizon", "1e9"])
    assert want in one_line_error(["gait-eval", str(gait), "--backend", "native",
                                   "--horizon", "1e9"])
    gait.write_text(json.dumps({"robot": "nao", "vector": [0.0] * 14, "horizon": 1e9}))
    assert want in one_line_error(["gait-eval", str(gait), "--backend", "native"])
    with pytest.raises(ProblemError, match=want):
        make_gait_problem("nao", backend="native", horizon=(MAX_CONTROL_STEPS + 1) * dt)
    problem = make_gait_problem("nao", backend="native", horizon=MAX_CONTROL_STEPS * dt)
    assert problem.n_steps == MAX_CONTROL_STEPS  # the largest allowed horizon is accepted
    with pytest.raises(ProblemError, match=want):
        problem.simulate(np.zeros(14), horizon=1e9)


@pytest.mark.slow
def test_gait_mjx_round_trip(tmp_path):
    """The MJX backend end to end; its stored parameters re-simulate to the same fitness."""
    out = tmp_path / "mjx"
    rec = last_json(invoke(["gait", "--backend", "mjx", "--ants", "4", "--iterations", "1",
                            "--horizon", "0.3", "--json", "--no-video", "--out",
                            str(out)]).stdout)
    assert rec["backend"] == "mjx"
    ev = last_json(invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "mjx",
                           "--json"]).stdout)
    assert ev["fitness"] == pytest.approx(rec["fitness"], abs=1e-5)


@pytest.mark.slow
def test_gait_init_warm_start(native_run, tmp_path):
    """``--init`` searches around a stored gait: every parameter stays within 15% of range."""
    from eaco_jax.gait.walk_engine import LOWER, UPPER

    _, out, rec = native_run
    warm = last_json(invoke(["gait", "--backend", "native", "--ants", "4", "--iterations", "1",
                             "--horizon", "0.5", "--json", "--no-video", "--init",
                             str(out / "best_gait.json"), "--out", str(tmp_path)]).stdout)
    start = np.asarray(rec["vector"])
    assert np.all(np.abs(np.asarray(warm["vector"]) - start) <= 0.15 * (UPPER - LOWER) + 1e-6)
    assert warm["init_fitness"] == pytest.approx(rec["fitness"], abs=1e-6)


def test_gait_eval_trials_and_export(native_run, tmp_path):
    """--trials replays under fresh randomised worlds; --export writes a run that replays on
    plain mujoco (no eaco code) to the same final state."""
    import mujoco

    _, out, _ = native_run
    npz = tmp_path / "run.npz"
    ev = last_json(invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native",
                           "--trials", "3", "--export", str(npz), "--json"]).stdout)
    t = ev["trials"]
    assert t["n"] == 3 and 0 <= t["falls"] <= 3 and t["backend"] == "native"
    assert np.isfinite(t["speed_mps_mean"]) and t["speed_mps_ci95"] >= 0
    run = np.load(npz)
    model = mujoco.MjModel.from_xml_string(str(run["model_xml"]))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = run["qpos"][0], run["qvel"][0]
    for u in run["ctrl"]:
        data.ctrl[:] = u
        mujoco.mj_step(model, data, nstep=int(run["substeps"]))
    np.testing.assert_allclose(data.qpos, run["qpos"][-1], atol=1e-9)
    assert "robust must be an integer >= 0" in one_line_error(["gait", "--robust", "-1"])
