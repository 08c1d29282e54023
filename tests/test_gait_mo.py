"""The multi-objective gait problem (speed x endurance, speed x electrical CoT).

A real native rollout (0.5 s, 2 randomised worlds) of the stored gait and a mid-box gait: the
objectives are the constrained problem's speed and the motor model's endurance / electrical CoT
for the same gaits and worlds, the violation is the constrained problem's without endurance,
and the hot stored gait, infeasible there for endurance too, stays infeasible here for its other
constraints. MOEACO runs on it through ``ea.minimize`` with vmapped seeds (native here; MJX,
slow to compile on a CPU, is marked slow).
"""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.gait.worlds import RobustConfig
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.problems.gait_mo import COT_CEILING, ENDURANCE_CEILING_MIN, make_gait_mo_problem
from eaco_jax.strategies import MOEACO

ROOT = Path(__file__).resolve().parents[1]
STORED = ROOT / "experiments" / "results" / "nao_best_gait.json"


@pytest.fixture(scope="module")
def gaits():
    """Both problems (0.5 s, native, 2 worlds), the stored and a mid-box gait, and the
    constrained problem's evaluation, constraints and quality metrics of them (batch 0)."""
    kw = dict(backend="native", horizon=0.5, robust=RobustConfig(R=2))
    con = make_gait_problem("nao", constrained=True, **kw)
    mo = make_gait_mo_problem("nao", "endurance", **kw)
    stored = np.asarray(json.loads(STORED.read_text())["vector"], np.float32)
    x = jnp.asarray(np.stack([stored, np.asarray((con.lower + con.upper) / 2, np.float32)]))
    ev = con.evaluate(x)
    _, _, g = con.constraints(x, con.worlds())
    metrics = con.metrics(x, quality=True)
    return con, mo, x, ev, np.asarray(g), metrics


def test_objectives_are_the_constrained_speed_and_the_motor_models_endurance(gaits):
    con, mo, x, ev, g, metrics = gaits
    assert mo.kind == "multiobjective" and mo.num_objectives == 2 and mo.stochastic
    assert mo.constraint_names == ("current", "slip", "drift", "falls")
    np.testing.assert_array_equal(np.asarray(mo.ref_point), [0.0, 0.0])
    e = mo.evaluate(x)
    assert e.f.shape == (2, 2) and e.violation.shape == (2,)
    np.testing.assert_allclose(np.asarray(e.f[:, 0]), np.asarray(ev.f), rtol=1e-6)
    endurance = np.minimum(np.asarray(metrics["min_endurance_min"]), ENDURANCE_CEILING_MIN)
    np.testing.assert_allclose(np.asarray(e.f[:, 1]), -endurance, rtol=1e-4)
    assert 0 < endurance[0] < 10.0  # the stored gait is hot: minutes, not an hour
    cot = mo.replace(second="cot")
    c = cot.evaluate(x)
    np.testing.assert_allclose(np.asarray(c.f[:, 0]), np.asarray(ev.f), rtol=1e-6)
    want = np.asarray(metrics["electrical_cot"])
    want = np.minimum(np.where(np.isfinite(want), want, COT_CEILING), COT_CEILING)
    np.testing.assert_allclose(np.asarray(c.f[:, 1]), want, rtol=1e-4)
    np.testing.assert_array_equal(np.asarray(cot.ref_point), [0.0, COT_CEILING])
    np.testing.assert_allclose(np.asarray(c.violation), np.asarray(e.violation), rtol=1e-6)


def test_violation_drops_endurance_and_a_violating_gait_is_infeasible(gaits):
    con, mo, x, ev, g, _ = gaits
    e = mo.evaluate(x)
    assert g[0, 0] > 0  # the stored gait breaks endurance in the constrained problem
    np.testing.assert_allclose(np.asarray(e.violation),
                               np.sum(np.maximum(g[:, 1:], 0.0), axis=-1), rtol=1e-5)
    np.testing.assert_allclose(np.asarray(e.violation),
                               np.asarray(ev.violation) - np.maximum(g[:, 0], 0.0), rtol=1e-5)
    assert np.all(np.asarray(e.violation) > 0)  # slip / drift over 0.5 s: infeasible
    rep = mo.report(np.asarray(x[0]), mo.worlds())
    assert rep["feasible"] is False and list(rep["constraints"]) == list(mo.constraint_names)
    assert rep["violation"] == pytest.approx(float(e.violation[0]), rel=1e-5)
    assert rep["f"] == pytest.approx(np.asarray(e.f[0]).tolist(), rel=1e-5)
    assert [k for k, r in rep["constraints"].items() if not r["holds"]]
    keyed = mo.evaluate(x, jax.random.PRNGKey(3))  # another optimisation batch
    assert not np.allclose(np.asarray(keyed.f), np.asarray(e.f))


def _minimize(backend: str, **kw) -> ea.Result:
    p = make_gait_mo_problem("nao", "cot", backend=backend, horizon=0.2,
                             robust=RobustConfig(R=2), **kw)
    r = ea.minimize(p, strategy=MOEACO(num_ants=4, archive_size=4), seed=[0, 1], iterations=2)
    assert r.state.archive_f.shape == (2, 4, 2)
    assert np.asarray(r.evaluations).tolist() == [8, 8]
    assert np.all(np.isfinite(np.asarray(r.state.archive_f)))  # every archive entry evaluated
    assert r.history["hypervolume"].shape == (2, 2)
    return r


def test_moeaco_runs_through_minimize_with_vmapped_seeds_native():
    r = _minimize("native")
    a, b = (np.asarray(r.state.archive_x[i]) for i in range(2))
    assert not np.allclose(a, b)  # two seeds, two searches


@pytest.mark.slow
def test_moeaco_runs_through_minimize_with_vmapped_seeds_mjx():
    _minimize("mjx", impl="jax")


def test_mo_gait_settings_errors():
    with pytest.raises(ProblemError, match="second must be"):
        make_gait_mo_problem("nao", "energy", backend="native")
    with pytest.raises(ProblemError, match="no 'constrained'"):
        make_gait_mo_problem("nao", backend="native", constrained=True)
    with pytest.raises(ProblemError, match="no electrical motor data"):
        make_gait_mo_problem("ant", backend="native")


def test_fronts_harness_scores_feasible_points_only(monkeypatch):
    """experiments/gait_fronts.py: the hypervolume counts feasible points only, and the front
    is the feasible non-dominated set (speed 0.3 at 5 min dominates speed 0.2 at 4 min)."""
    monkeypatch.syspath_prepend(str(ROOT / "experiments"))
    import gait_fronts as gf

    f = np.asarray([[-0.3, -5.0], [-0.2, -4.0], [-0.1, -20.0], [-0.5, -30.0]])
    v = np.asarray([0.0, 0.0, 0.0, 1.0])  # the best point is infeasible
    ref = np.zeros(2)
    assert gf.hypervolume(f, v, ref) == pytest.approx(0.3 * 5.0 + 0.1 * 15.0)
    assert gf.hypervolume(f, np.ones(4), ref) == 0.0
    np.testing.assert_array_equal(gf.nondominated(f, v), f[[0, 2]])
    assert gf._front_rows(f, v).tolist() == [0, 2]
    np.testing.assert_allclose(gf.natural(f[:1], "endurance"), [[0.3, 5.0]])


def test_front_candidates_keep_the_threshold_and_pick_by_the_fixed_rule(monkeypatch, tmp_path):
    """experiments/front_candidates.py: ``write`` keeps the front points at or past both
    thresholds, as gait records on the given seed; ``pick`` ranks by worlds failing any
    constraint, then falls, then speed, and refuses a table of another stream."""
    import json

    monkeypatch.syspath_prepend(str(ROOT / "experiments"))
    import front_candidates as fc

    x = [[0.1] * 14, [0.2] * 14, [0.3] * 14]
    seed_row = {"seed": 0, "rescored_front": [[-0.36, -10.5], [-0.34, -20.0], [-0.40, -9.0]],
                "rescored_front_x": x}
    fronts = {"problem": {"second": "endurance", "init": str(tmp_path / "none.json"),
                          "backend": "mjx", "horizon_s": 20.0, "steering": None,
                          "target_noise": 0.0004},
              "seeds": {"scoring": "selection"},
              "arms": {"colony": {"seeds": [seed_row]}, "nsga2": {"seeds": []}}}
    (tmp_path / "f.json").write_text(json.dumps(fronts))
    rows = fc.write(tmp_path / "f.json", 0.35, 10.0, 27, tmp_path / "c")
    assert [(r["speed"], r["endurance_min"]) for r in rows] == [(0.36, 10.5)]
    rec = json.loads((tmp_path / "c" / "c00.json").read_text())
    assert rec["seed"] == 27 and rec["vector"] == x[0]

    def table(name, met, falls, speed, stream="selection"):
        (tmp_path / "c" / f"{name}_sel64.json").write_text(json.dumps(
            {"stream": stream, "worlds": 64, "all_constraints_met": met,
             "falls": {"falls": falls}, "speed_mean": speed, "seed": 27}))

    table("c00", 60, 0, 0.40)
    table("c01", 63, 1, 0.30)
    table("c02", 63, 0, 0.31)
    table("c03", 63, 0, 0.35)
    res = fc.pick(tmp_path / "c")
    assert [r["name"] for r in res["ranked"]] == ["c03", "c02", "c01", "c00"]
    table("c04", 64, 0, 0.2, stream="test")
    with pytest.raises(SystemExit, match="selection-stream"):
        fc.pick(tmp_path / "c")


def test_front_candidates_take_the_most_economical_fast_point_of_each_cot_front(monkeypatch,
                                                                               tmp_path):
    """From a speed x CoT front ``write`` takes, per arm and seed, the one point at or past the
    speed bar with the lowest CoT (a front with none gives nothing)."""
    import json

    monkeypatch.syspath_prepend(str(ROOT / "experiments"))
    import front_candidates as fc

    x = [[0.1] * 14, [0.2] * 14, [0.3] * 14, [0.4] * 14]
    front = [[-0.50, 1.40], [-0.40, 1.20], [-0.36, 1.15], [-0.30, 1.05]]
    fronts = {"problem": {"second": "cot", "init": str(tmp_path / "none.json"),
                          "backend": "mjx", "horizon_s": 20.0, "steering": None,
                          "target_noise": 0.0004},
              "seeds": {"scoring": "selection"},
              "arms": {"colony": {"seeds": [{"seed": 3, "rescored_front": front,
                                             "rescored_front_x": x}]},
                       "nsga2": {"seeds": [{"seed": 3, "rescored_front": [[-0.2, 1.0]],
                                            "rescored_front_x": [x[0]]}]}}}
    (tmp_path / "f.json").write_text(json.dumps(fronts))
    rows = fc.write(tmp_path / "f.json", 0.35, 10.0, 28, tmp_path / "c")
    assert [(r["arm"], r["speed"], r["cot"]) for r in rows] == [("colony", 0.36, 1.15)]
    rec = json.loads((tmp_path / "c" / "c00.json").read_text())
    assert rec["vector"] == x[2] and rec["front"]["endurance_min"] is None
