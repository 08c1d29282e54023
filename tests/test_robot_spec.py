"""Robot specs from any path: a spec written outside the repository runs `eaco gait` and
`eaco gait-eval`; bad specs are one line naming the field; a checkpoint pins its spec; the
vendored Menagerie robots load, stand and convert to MJX."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.errors import ProblemError
from eaco_jax.gait.robot import ROBOTS_DIR, known_robots, load_model, load_robot, stand_qpos

TINY = ["--backend", "native", "--ants", "4", "--iterations", "2", "--horizon", "0.5",
        "--seed", "3", "--json"]


def last_json(stdout: str) -> dict:
    return json.loads(stdout.strip().splitlines()[-1])


@pytest.fixture()
def my_robot(tmp_path) -> Path:
    """The ant as a user's own robot: its MJCF and a renamed spec in a folder outside the repo."""
    folder = tmp_path / "my_robot"
    folder.mkdir()
    shutil.copy(load_robot("ant").xml_path, folder / "walker.xml")
    raw = json.loads((ROBOTS_DIR / "ant.json").read_text())
    raw.update(name="walker", xml="walker.xml")
    (folder / "walker.json").write_text(json.dumps(raw))
    return folder / "walker.json"


def edit(spec: Path, **fields) -> Path:
    raw = json.loads(spec.read_text())
    for key, value in fields.items():
        if value is None:
            raw.pop(key)
        else:
            raw[key] = value
    spec.write_text(json.dumps(raw))
    return spec


def test_spec_outside_the_repo_runs_gait_and_gait_eval(my_robot, tmp_path):
    assert not my_robot.resolve().is_relative_to(ROBOTS_DIR.parent)
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["gait", "--robot", str(my_robot), *TINY, "--out", str(out)])
    assert res.exit_code == 0, (res.output, res.exception)
    record = last_json(res.stdout)
    assert record["robot"] == "walker"
    assert record["robot_spec"] == str(my_robot.resolve())
    assert record["robot_sha256"] == load_robot(my_robot).digest
    stored = json.loads((out / "best_gait.json").read_text())
    assert stored["robot_spec"] == str(my_robot.resolve())
    # gait-eval finds the spec through the stored gait and reproduces its fitness
    res = CliRunner().invoke(app, ["gait-eval", str(out / "best_gait.json"), "--backend",
                                   "native", "--json"])
    assert res.exit_code == 0, (res.output, res.exception)
    again = last_json(res.stdout)
    assert again["robot"] == "walker"
    assert again["fitness"] == pytest.approx(record["fitness"], abs=1e-6)
    # the same robot as the shipped ant: the same physics
    ant = load_robot("ant")
    mine = load_robot(str(my_robot))
    assert mine.joint_lower == ant.joint_lower and mine.stand_ctrl == ant.stand_ctrl
    assert mine.source == str(my_robot.resolve()) and not mine.builtin and ant.builtin


def test_make_gait_problem_takes_a_spec_path(my_robot):
    from eaco_jax.problems.gait import make_gait_problem

    problem = make_gait_problem(str(my_robot), backend="native", horizon=0.5)
    assert problem.spec.name == "walker" and problem.spec.xml_path.endswith("walker.xml")


def test_relative_spec_path_is_made_absolute(my_robot, monkeypatch):
    from eaco_jax.runs.gait import GaitSettings

    monkeypatch.chdir(my_robot.parent)
    s = GaitSettings(robot="walker.json")
    assert s.robot == str(my_robot.resolve())
    assert GaitSettings(robot="nao").robot == "nao"


def _drop_actuator(spec: Path) -> Path:
    xml = spec.parent / "walker.xml"
    text = xml.read_text()
    line = next(ln for ln in text.splitlines() if "<motor" in ln and "hip_1" in ln)
    xml.write_text(text.replace(line, ""))
    return spec


BAD = {
    "missing joint": (dict(joint_names=["hip_9", "ankle_4", "hip_1", "ankle_1", "hip_2",
                                        "ankle_2", "hip_3", "ankle_3"]),
                      r"joint_names\[0\] 'hip_9' is not a joint of the MJCF"),
    "foot not in MJCF": (dict(foot_geoms=["left_foot_geom", "nope"]),
                         r"foot_geoms\[1\] 'nope' is not a geom of the MJCF"),
    "torso not a body": (dict(torso_body="chest"), r"torso_body 'chest' is not a body"),
    "torso site": (dict(torso_site="imu"), r"torso_site 'imu' is not a site"),
    "upside down": (dict(stand_root=[0, 0, 0.55, 0, 1, 0, 0]),
                    r"foot_geoms\[0\] 'left_foot_geom' is not below its hip"),
    "unknown gait": (dict(gait="hexapod"), r"gait 'hexapod' is not one of biped, quadruped"),
    "wrong type": (dict(control_dt="fast"), r"field 'control_dt' must be a finite number"),
    "missing field": (dict(fall_height=None), r"field 'fall_height' is missing"),
    "stand length": (dict(stand_ctrl=[0.0, 1.0]), r"stand_ctrl has 2 values for 8 joint_names"),
    "stand outside range": (dict(stand_ctrl=[0.0, 1.0, 0.0, 1.0, 0.0, -1.0, 0.0, -3.0]),
                            r"stand_ctrl\[7\] = -3.0 is outside joint 'ankle_3'"),
    "control rate": (dict(control_dt=0.015), r"control_dt 0.015 must be a positive multiple"),
    "xml missing": (dict(xml="nowhere.xml"), r"xml: .*nowhere.xml does not exist"),
    "joint order": (dict(joint_names=["ankle_4", "hip_4", "hip_1", "ankle_1", "hip_2",
                                      "ankle_2", "hip_3", "ankle_3"],
                         stand_ctrl=[1.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, -1.0]),
                    r"joint_names must match the MJCF's actuators"),
    "solver": (dict(solver={"fast": {"timestep": 0.01, "iterations": 1}}),
               r"solver.fast: field 'ls_iterations' is missing"),
    "actuator missing": (_drop_actuator, r"joint_names\[2\] 'hip_1': no actuator"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_spec_is_one_line_naming_the_field(my_robot, case):
    change, pattern = BAD[case]
    spec = change(my_robot) if callable(change) else edit(my_robot, **change)
    with pytest.raises(ProblemError, match=pattern) as err:
        load_robot(str(spec))
    assert "\n" not in str(err.value)
    assert str(spec.resolve()) in str(err.value)  # says which file


def test_bad_robot_arguments():
    with pytest.raises(ProblemError, match="is an MJCF model, not a robot spec"):
        load_robot("path/to/robot.xml")
    with pytest.raises(ProblemError, match="robot spec nowhere/spec.json does not exist"):
        load_robot("nowhere/spec.json")
    with pytest.raises(ProblemError, match="unknown robot 'atlas'; known robots: ant, go2, nao"):
        load_robot("atlas")


def test_cli_bad_spec_is_one_error_line(my_robot, tmp_path):
    edit(my_robot, gait="hexapod")
    res = CliRunner().invoke(app, ["gait", "--robot", str(my_robot), *TINY,
                                   "--out", str(tmp_path / "o")])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: robot spec ")
    assert "gait 'hexapod'" in lines[0]


def test_resume_refuses_a_changed_spec(my_robot, tmp_path):
    ckpt = tmp_path / "ckpt"
    args = ["gait", "--robot", str(my_robot), *TINY, "--out", str(tmp_path / "o"),
            "--checkpoint-dir", str(ckpt), "--checkpoint-every", "1"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, (res.output, res.exception)
    first = last_json(res.stdout)
    stored = json.loads((ckpt / "run.json").read_text())
    assert stored["robot_spec"] == {"path": str(my_robot.resolve()),
                                    "sha256": load_robot(my_robot).digest}
    res = CliRunner().invoke(app, ["resume", str(ckpt), "--json"])
    assert res.exit_code == 0, (res.output, res.exception)
    assert last_json(res.stdout)["fitness"] == first["fitness"]
    # one changed number in the MJCF: the digest covers it
    xml = my_robot.parent / "walker.xml"
    xml.write_text(xml.read_text().replace('density="5.0"', 'density="6.0"', 1))
    res = CliRunner().invoke(app, ["resume", str(ckpt), "--json"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "changed since this checkpoint was written" in lines[0]


# --------------------------------------------------------------------------- vendored robots
def test_robots_folder_is_data_with_licences():
    assert not (ROBOTS_DIR / "__init__.py").exists()
    assert {"nao", "ant", "op3", "go2"} <= set(known_robots())
    for folder, words in (("robotis_op3", "Apache License"), ("unitree_go2", "Unitree")):
        assert words in (ROBOTS_DIR / folder / "LICENSE").read_text()
        assert "What changed here" in (ROBOTS_DIR / folder / "README.md").read_text()


@pytest.mark.parametrize("name,mass,nu", [("op3", 3.147, 20), ("go2", 15.206, 12)])
def test_menagerie_robot_stands_two_seconds_and_converts_to_mjx(name, mass, nu):
    from mujoco import mjx

    spec = load_robot(name)
    model = load_model(spec)
    assert model.nu == nu and sum(model.body_mass) == pytest.approx(mass, abs=0.01)
    assert all(np.isfinite(spec.force_limit))  # Menagerie's servos are force-limited
    data = mujoco.MjData(model)
    data.qpos[:] = stand_qpos(spec, model)
    data.ctrl[:] = spec.stand_ctrl
    mujoco.mj_forward(model, data)
    torso = model.body(spec.torso_body).id
    start = data.xpos[torso].copy()
    for _ in range(int(round(2.0 / model.opt.timestep))):
        mujoco.mj_step(model, data)
    end = data.xpos[torso]
    assert abs(end[2] - start[2]) < 0.03 and np.linalg.norm(end[:2] - start[:2]) < 0.06
    assert data.xmat[torso].reshape(3, 3)[2, 2] > np.cos(np.radians(5))  # upright
    mx = mjx.put_model(model)
    assert mx.nu == nu
    dx = mjx.put_data(model, data)
    assert dx.qpos.shape == (model.nq,)
