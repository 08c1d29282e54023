"""The first hour of a new user: usage errors, ``--params`` on every search command, what the
run commands print (trials, export, summaries, the progress bar's sign), MuJoCo's warnings and
the ask/tell contract of a continuous strategy."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app

TINY_GAIT = ["gait", "--robot", "nao", "--backend", "native", "--ants", "4", "--iterations",
             "2", "--horizon", "0.5", "--seed", "1", "--no-video"]


def one_line_error(args: list[str]) -> str:
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, (args, res.output)
    err = res.stderr.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    assert "Traceback" not in res.output and "╭" not in res.output, res.output
    return err


def test_usage_errors_are_one_line_naming_the_help():
    err = one_line_error(["gait", "--no-such-flag", "1"])
    assert "No such option: --no-such-flag" in err and "(see 'eaco gait --help')" in err
    err = one_line_error(["resume"])
    assert "Missing argument" in err and "(see 'eaco resume --help')" in err
    err = one_line_error(["tsp", "burma14", "--ants", "abc"])
    assert "'--ants'" in err and "(see 'eaco tsp --help')" in err
    assert "No such command 'tspp'" in one_line_error(["tspp"])


def test_continuous_tell_with_plain_costs_names_evaluation():
    """A numpy array told to a continuous strategy is one line naming ea.Evaluation, raised
    before tracing (not a tracer's AttributeError)."""
    import jax
    import numpy as np

    from eaco_jax.errors import ConfigError
    from eaco_jax.problems import functions
    from eaco_jax.strategies import ContinuousEACO

    problem = functions.sphere()
    strategy = ContinuousEACO(num_ants=4, archive_size=6, refine_ants=0, repair_steps=0)
    state = strategy.init(jax.random.key(0), problem)
    x, state = strategy.ask(jax.random.key(1), state, problem)
    costs = np.sum(np.asarray(x) ** 2, axis=1)
    with pytest.raises(ConfigError, match=r"needs fitness as ea\.Evaluation\(f, violation\)") \
            as err:
        strategy.tell(state, x, costs, problem)
    assert "\n" not in str(err.value) and "got ndarray" in str(err.value)


@pytest.mark.parametrize("command", [
    ["tsp", "burma14", "--local-search", "none", "--params", "rho=0.1"],
    ["constrained", "g06", "--repair-steps", "0", "--params", "p_repair=0.3"],
])
def test_params_without_effect_are_refused_by_single_runs(command, tmp_path):
    """A --params field the switches leave unused is refused, as a sweep refuses sweeping it."""
    name = command[-1].split("=")[0]
    err = one_line_error([*command, "--iterations", "1", "--out", str(tmp_path)])
    assert f"--params: {name} has no effect unless " in err and f"or drop {name})" in err


@pytest.mark.parametrize(("field", "why"), [
    ("p_repair", "no gradient repair on gait problems"),
    ("repair_margin", "no gradient repair on gait problems; no SQP refinement on gait problems"),
])
def test_gait_params_without_effect_name_nothing_gait_cannot_set(field, why, tmp_path):
    """eaco gait offers no repair_steps or refine_ants: a field only they would make act is
    refused with the reason, not with 'set that too'."""
    err = one_line_error(["gait", "--params", f"{field}=0.5", "--iterations", "1", "--out",
                          str(tmp_path)])
    assert err == f"error: --params: {field} has no effect in eaco gait ({why}); drop it"


def test_gait_penalty_param_names_the_constraint_method(tmp_path):
    """The colony's penalty coefficient acts with --constrained --constraint-method penalty,
    which eaco gait can set: the refusal names that switch."""
    err = one_line_error(["gait", "--params", "penalty=0.5", "--iterations", "1", "--out",
                          str(tmp_path)])
    assert "penalty has no effect unless constraint_method='penalty'" in err


def test_a_switch_the_command_can_set_is_still_named():
    """Where one name of the switch is settable, the line names the switch as before."""
    from eaco_jax.errors import ConfigError
    from eaco_jax.runs.base import refuse_inactive, switch_names
    from eaco_jax.strategies import ContinuousEACO

    assert switch_names("repair_steps > 0 or refine_ants > 0") == ["repair_steps",
                                                                   "refine_ants"]
    assert switch_names("constraint_method='epsilon'") == ["constraint_method"]
    strategy = ContinuousEACO(num_ants=4, archive_size=6, refine_ants=0, repair_steps=0)
    params = strategy.default_params()
    with pytest.raises(ConfigError, match=r"^repair_margin has no effect unless repair_steps "
                       r"> 0 or refine_ants > 0 \(set that too, or drop repair_margin\)$"):
        refuse_inactive(strategy, params, ["repair_margin"],
                        fixed={"repair_steps": "no repair"}, command="eaco x")


def test_gait_params_are_checked():
    err = one_line_error(["gait", "--params", "q0=2"])
    assert "ContinuousParams.q0=2.0 is outside its range [0, 1]" in err
    assert "unknown ContinuousParams field(s) ['bogus']" in one_line_error(
        ["gait", "--params", "bogus=1"])


def test_falls_interval_is_clopper_pearson():
    from eaco_jax.runs.gait import falls_interval

    # exact bounds: 0/3 -> 1 - 0.025**(1/3); 3/3 -> 0.025**(1/3); 1/10, 5/100 from tables
    assert falls_interval(0, 3) == pytest.approx((0.0, 1 - 0.025 ** (1 / 3)))
    assert falls_interval(3, 3) == pytest.approx((0.025 ** (1 / 3), 1.0))
    assert falls_interval(1, 10) == pytest.approx((0.002529, 0.445016), abs=1e-6)
    assert falls_interval(5, 100) == pytest.approx((0.016432, 0.112835), abs=1e-6)


@pytest.fixture(scope="module")
def gait_runs(tmp_path_factory):
    """The tiny native gait twice (same seed): with --params, --trials and the progress bar,
    and with default params as --json."""
    base = tmp_path_factory.mktemp("first_hour")
    out_a, out_b = base / "a", base / "b"
    res_a = CliRunner().invoke(app, [*TINY_GAIT, "--params", "rho=0.05", "--trials", "3",
                                     "--out", str(out_a)])
    assert res_a.exit_code == 0, (res_a.output, res_a.exception)
    res_b = CliRunner().invoke(app, [*TINY_GAIT, "--json", "--out", str(out_b)])
    assert res_b.exit_code == 0, (res_b.output, res_b.exception)
    rec_a = json.loads((out_a / "best_gait.json").read_text())
    rec_b = json.loads(res_b.stdout.strip().splitlines()[-1])
    return res_a, rec_a, rec_b, out_a


def test_gait_params_reach_the_colony(gait_runs):
    _, rec_a, rec_b, _ = gait_runs
    assert rec_a["seed"] == rec_b["seed"] and rec_a["iterations"] == rec_b["iterations"]
    assert rec_a["vector"] != rec_b["vector"]  # rho=0.05 samples other gaits than rho=0.6


def test_gait_progress_bar_shows_the_fitness(gait_runs):
    import re

    res_a, rec_a, _, _ = gait_runs
    assert rec_a["search_fitness"] > 0
    shown = [float(v) for v in re.findall(r"best=(-?[0-9.e+-]+)", res_a.stderr)]
    assert shown and shown[-1] == pytest.approx(rec_a["search_fitness"], rel=2e-3)


def test_trials_and_export_are_printed(gait_runs, tmp_path):
    from eaco_jax.runs.gait import falls_interval

    res_a, rec_a, _, out_a = gait_runs
    t = rec_a["trials"]
    lo, hi = falls_interval(t["falls"], 3)
    assert t["fall_rate_ci95"] == pytest.approx([lo, hi])
    lines = res_a.stdout.strip().splitlines()
    first = next(i for i, line in enumerate(lines)
                 if line.startswith("nao (native, 0.5 s): speed "))
    assert lines[first + 1].startswith("actuator envelope (motor data: ")
    assert lines[-2].startswith("motors: ")
    assert lines[-1].startswith(
        f"trials (test stream): 3 worlds, {t['falls']} fall{'' if t['falls'] == 1 else 's'} "
        f"({100 * t['falls'] / 3:.1f}%, 95% CI {100 * lo:.1f}-{100 * hi:.1f}%), speed "
        f"{t['speed_mps_mean']:.3f} +/- {t['speed_mps_ci95']:.3f} m/s (mean, 95% CI); "
        "constraints (worst world): ")
    npz = tmp_path / "run.npz"
    res = CliRunner().invoke(app, ["gait-eval", str(out_a / "best_gait.json"), "--backend",
                                   "native", "--trials", "2", "--export", str(npz)])
    assert res.exit_code == 0, (res.output, res.exception)
    lines = res.stdout.strip().splitlines()
    assert lines[-2].startswith("trials (test stream): 2 worlds, ")
    assert lines[-1] == f"export: wrote {npz}"
    assert npz.is_file()


def test_constrained_and_resume_print_the_one_line_summary(tmp_path):
    """``eaco constrained`` prints one line as the other commands do; ``eaco resume`` prints
    the resumed kind's own summary (not a key: value dump)."""
    import re

    ck = tmp_path / "ck"
    res = CliRunner().invoke(app, ["constrained", "sphere", "--iterations", "3", "--ants", "4",
                                   "--archive-size", "4", "--refine-ants", "0",
                                   "--repair-steps", "0", "--checkpoint-dir", str(ck)])
    assert res.exit_code == 0, (res.output, res.exception)
    line = re.compile(r"sphere10: f \S+ \(f\* 0, error \S+\), feasible, 12 evaluations, "
                      r"\d+\.\d s")
    assert len(res.stdout.strip().splitlines()) == 1 and line.fullmatch(res.stdout.strip())
    again = CliRunner().invoke(app, ["resume", str(ck)])
    assert again.exit_code == 0, (again.output, again.exception)
    assert line.fullmatch(again.stdout.strip()), again.stdout


UNSTABLE = ('<mujoco><option timestep="1"/><worldbody><body><freejoint/><geom size=".1"/>'
            '</body></worldbody></mujoco>')


def test_mujoco_warnings_reach_python_not_a_log_file(tmp_path, monkeypatch):
    """A diverging simulation on the native pool: MuJoCo's warning arrives as one Python
    warning per kind, and no MUJOCO_LOG.TXT appears in the working directory."""
    import warnings

    import mujoco
    import numpy as np

    from eaco_jax.gait import rollout_native

    monkeypatch.chdir(tmp_path)
    model = mujoco.MjModel.from_xml_string(UNSTABLE)
    data = mujoco.MjData(model)
    data.qvel[:] = 1e30
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros((4, mujoco.mj_stateSize(model, full)))
    mujoco.mj_getState(model, data, state[0], full)
    state[:] = state[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rollout_native._pool(2).rollout([model] * 4, [mujoco.MjData(model) for _ in range(2)],
                                        state, np.zeros((4, 3, 0)))
    texts = {str(w.message) for w in caught if w.category is rollout_native.MujocoWarning}
    assert texts == {"MuJoCo: Nan, Inf or huge value in QVEL. The simulation is unstable."}
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
