"""The constrained gait search and the three world key streams.

Constraints: hand-made per-world results violate one constraint each and are reported with that
constraint's normalised violation only; a real (native, short) rollout of the stored gait breaks
the motor constraints; ``eaco gait --constrained`` runs end to end. Streams: optimisation,
selection and test worlds of a seed are disjoint and reproducible; gait-eval's trials default to
the test stream; finalists are chosen on the selection stream.
"""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.errors import ProblemError
from eaco_jax.gait import constraints as gc
from eaco_jax.gait.motors import motor_model
from eaco_jax.gait.worlds import STREAMS, RobustConfig, optimisation_key, stream_key
from eaco_jax.problems.gait import make_gait_problem

ROOT = Path(__file__).resolve().parents[1]
STORED = ROOT / "experiments" / "results" / "nao_best_gait.json"
NU = 22


def _results(m: int = 6, r: int = 2) -> dict[str, jnp.ndarray]:
    """Per-world results of ``m`` gaits that meet every constraint: 2 m walked, 1 cm slip."""
    return {"winding_10min_c": jnp.full((m, r, NU), 50.0),
            "peak_current_max_frac": jnp.full((m, r), 0.5),
            "foot_slip_m": jnp.full((m, r), 0.01), "distance_m": jnp.full((m, r), 2.0),
            "drift_deg": jnp.full((m, r), 1.0), "fell": jnp.zeros((m, r), bool)}


def test_each_constraint_reports_its_own_violation():
    """Row i + 1 breaks constraint i in world 1 only (the worst world counts): its g is the
    excess over the limit in units of the limit, the other entries stay <= 0."""
    res = _results()
    res["winding_10min_c"] = res["winding_10min_c"].at[1, 1, 7].set(100.0)  # (100-75)/50
    res["peak_current_max_frac"] = res["peak_current_max_frac"].at[2, 1].set(1.3)
    res["foot_slip_m"] = res["foot_slip_m"].at[3, 1].set(0.2)  # 0.1 m/m: (0.1-0.05)/0.05
    res["drift_deg"] = res["drift_deg"].at[4, 1].set(15.0)  # 20 s: (15-10)/10
    res["fell"] = res["fell"].at[5, 1].set(True)  # 1 of 2 worlds
    mm = motor_model(make_gait_problem("nao", backend="native").spec)
    vals = gc.values(res)
    g = np.asarray(gc.normalised(vals, mm, 20.0, 2))
    assert list(vals) == list(gc.CONSTRAINTS) and g.shape == (6, 5)
    assert np.all(g[0] <= 0)
    expected = [0.5, 0.3 - gc.CURRENT_ROUNDING, 1.0, 0.5, 0.5]
    for i, want in enumerate(expected):
        row = g[i + 1]
        assert row[i] == pytest.approx(want, rel=1e-5), gc.CONSTRAINTS[i]
        assert np.all(np.delete(row, i) <= 0), gc.CONSTRAINTS[i]
    np.testing.assert_allclose(np.asarray(gc.violation(jnp.asarray(g))), [0.0, *expected],
                               rtol=1e-5)
    table = gc.table({k: np.asarray(v)[5] for k, v in vals.items()}, g[5], mm, 20.0, 2)
    assert [k for k, row in table.items() if not row["holds"]] == ["falls"]
    assert table["falls"]["n"] == 2 and table["falls"]["fall_rate_ci95"][0] > 0
    assert table["endurance"]["limit"] == 75.0 and table["endurance"]["margin"] == 25.0


def test_drift_limit_scales_with_the_horizon_and_turns_drop_it():
    assert [gc.drift_limit_deg(h) for h in (1.0, 5.0, 10.0, 20.0, 600.0)] == [
        2.5, 2.5, 5.0, 10.0, 10.0]
    res = _results(1)
    res["drift_deg"] = res["drift_deg"].at[0, 0].set(4.0)
    mm = motor_model(make_gait_problem("nao", backend="native").spec)
    assert np.asarray(gc.normalised(gc.values(res), mm, 10.0, 2))[0, 3] == pytest.approx(-0.2)
    assert np.asarray(gc.normalised(gc.values(res), mm, 4.0, 2))[0, 3] == pytest.approx(0.6)
    assert "drift" not in gc.values(res, turn="left")
    res["winding_10min_c"] = res["winding_10min_c"].at[0, 0, 0].set(jnp.nan)  # diverged
    assert np.asarray(gc.normalised(gc.values(res), mm, 20.0, 2))[0, 0] == gc.NONFINITE_VIOLATION


def test_streams_are_disjoint_and_reproducible():
    """Worlds of the optimisation (key-less batch and driver-keyed batches), selection and test
    streams of one seed share no friction value; the same seed and stream give the same
    worlds; another seed gives other worlds."""
    p = make_gait_problem("nao", backend="native", horizon=2.0, robust=RobustConfig(R=64, seed=3))
    draws = {
        "optimisation": [p.worlds(), p.worlds(optimisation_key(3, jax.random.PRNGKey(9)))],
        "selection": [p.worlds(stream_key(3, "selection"))],
        "test": [p.worlds(stream_key(3, "test")), p.worlds(stream_key(3, "test", 1))],
    }
    seen = {s: np.concatenate([np.asarray(w.friction) for w in ws]) for s, ws in draws.items()}
    for a in STREAMS:
        for b in STREAMS:
            if a < b:
                assert not set(seen[a].tolist()) & set(seen[b].tolist()), (a, b)
                assert not np.array_equal(np.asarray(draws[a][0].push_start),
                                          np.asarray(draws[b][0].push_start))
    again = p.worlds(stream_key(3, "test"))
    for f in ("friction", "mass_scale", "stall_scale", "init_dq", "push_force"):
        np.testing.assert_array_equal(np.asarray(getattr(again, f)),
                                      np.asarray(getattr(draws["test"][0], f)))
    assert not np.array_equal(np.asarray(p.worlds(stream_key(4, "test")).friction),
                              seen["test"][:64])
    # the driver's key picks a batch inside the optimisation stream (the documented derivation)
    k = jax.random.PRNGKey(9)
    w0, w1 = np.asarray(jax.random.bits(k, (2,), jnp.uint32))
    root = jax.random.fold_in(jax.random.PRNGKey(3), STREAMS["optimisation"])
    want = jax.random.fold_in(jax.random.fold_in(root, w0), w1)
    np.testing.assert_array_equal(np.asarray(optimisation_key(3, k)), np.asarray(want))


@pytest.fixture(scope="module")
def short():
    """The stored gait and a mid-box gait on a 0.5 s constrained problem in 2 worlds."""
    p = make_gait_problem("nao", backend="native", horizon=0.5, robust=RobustConfig(R=2),
                          constrained=True)
    stored = np.asarray(json.loads(STORED.read_text())["vector"], np.float32)
    mid = np.asarray((p.lower + p.upper) / 2, np.float32)
    return p, stored, mid


def test_constrained_problem_evaluates_a_real_rollout(short):
    """f = -speed and violation = the sum of the normalised excesses, from one rollout; the
    stored gait, hot, breaks the endurance constraint in the host re-check; its current stops
    at the limit (the limits are in the physics), so the current constraint holds."""
    p, stored, mid = short
    assert p.constrained and p.num_inequality == 5 and p.stochastic
    x = jnp.asarray(np.stack([stored, mid]))
    ev = jax.jit(p.evaluate)(x)  # key-less: the optimisation stream's batch 0
    speed, vals, g = jax.jit(p.constraints)(x, p.worlds())
    np.testing.assert_allclose(np.asarray(ev.f), -np.asarray(speed), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(ev.violation),
                               np.sum(np.maximum(np.asarray(g), 0), -1), rtol=1e-6)
    assert np.all(np.asarray(ev.violation) > 0)
    check = p.host_check(stored)
    assert check["feasible"] is False and check["cost"] == float("inf")
    assert check["f"] == pytest.approx(float(ev.f[0]), rel=1e-5)
    assert check["violation"] == pytest.approx(float(ev.violation[0]), rel=1e-5)
    c = check["constraints"]
    assert list(c) == list(gc.CONSTRAINTS)
    assert not c["endurance"]["holds"] and c["endurance"]["value"] > 75.0
    assert c["current"]["holds"] and 0.99 < c["current"]["value"] <= 1.0 + 1e-5
    for row in c.values():
        assert row["margin"] == pytest.approx(row["limit"] - row["value"])
        assert row["holds"] == (row["g"] <= 0)
    keyed = jax.jit(p.evaluate)(x, jax.random.PRNGKey(1))  # another optimisation batch
    assert not np.allclose(np.asarray(keyed.violation), np.asarray(ev.violation))


def test_finalists_are_chosen_on_the_selection_stream(short):
    """The archive's first gait is the worse one on the selection worlds: the selection keeps
    the second, scored in the selection stream's worlds of the seed."""
    from eaco_jax.gait.worlds import stream_key as sk
    from eaco_jax.runs.gait import select_finalists

    p, stored, mid = short
    best, rec = select_finalists(p, np.stack([mid, stored]), k=2, n=3, seed=5)
    assert rec["stream"] == "selection" and rec["worlds"] == 3
    viol = [r["violation"] for r in rec["finalists"]]
    assert viol[1] < viol[0] and rec["chosen"] == 1
    np.testing.assert_array_equal(best, stored)
    wide = p.replace(robust=RobustConfig(R=3))
    speed, _, _ = jax.jit(wide.constraints)(jnp.asarray(np.stack([mid, stored])),
                                            wide.worlds(sk(5, "selection"), 3))
    np.testing.assert_allclose([r["score"] for r in rec["finalists"]], np.asarray(speed),
                               rtol=1e-6)


def _invoke(args):
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, (res.output, res.exception)
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_constrained_gait_cli_end_to_end_and_gait_eval_on_test(tmp_path):
    """``eaco gait --constrained`` (native, 4 ants, 2 iterations, 0.5 s, 2 worlds, warm start
    from the stored gait) records the search's violation, the kept gait's constraints on the
    selection stream and test-stream trials; ``eaco gait-eval --trials`` defaults to the test
    stream of the file's seed."""
    out = tmp_path / "c"
    rec = _invoke(["gait", "--constrained", "--backend", "native", "--ants", "4",
                   "--iterations", "2", "--horizon", "0.5", "--robust", "2", "--seed", "2",
                   "--init", str(STORED), "--finalists", "2", "--select-worlds", "2",
                   "--trials", "2", "--json", "--no-video", "--out", str(out)])
    assert rec["constraint_method"] == "epsilon" and rec["robust"]["stream"] == "optimisation"
    assert len(rec["history_violation"]) == 2 and min(rec["history_violation"]) > 0
    assert rec["search"]["violation"] > 0 and rec["search"]["feasible"] is False
    c = rec["constraints"]
    assert c["stream"] == "selection" and c["worlds"] == 2
    assert set(c["constraints"]) == set(gc.CONSTRAINTS)
    assert rec["selection"]["stream"] == "selection"
    t = rec["trials"]
    assert t["stream"] == "test" and t["seed"] == 2 and t["n"] == 2
    assert len(t["fall_rate_ci95"]) == 2 and "constraints" in t
    ev = _invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native",
                  "--trials", "2", "--json"])
    assert ev["trials"]["stream"] == "test" and ev["trials"]["seed"] == 2
    assert ev["trials"]["speed_mps_mean"] == pytest.approx(t["speed_mps_mean"], rel=1e-6)
    sel = _invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native",
                   "--trials", "2", "--stream", "selection", "--json"])
    assert sel["trials"]["stream"] == "selection"
    assert sel["trials"]["speed_mps_mean"] != ev["trials"]["speed_mps_mean"]


def test_constrained_settings_errors():
    for args, text in (
        (["gait", "--constraint-method", "deb"], "needs --constrained"),
        (["gait", "--constrained", "--penalty", "cot"], "drop --penalty"),
        (["gait", "--constrained", "--robot", "ant"], "no electrical motor data"),
    ):
        res = CliRunner().invoke(app, args)
        assert res.exit_code == 2, (args, res.output)
        assert text in res.output and res.output.strip().count("\n") == 0, res.output


def test_search_margin_tightens_endurance_slip_and_drift_only():
    g = jnp.zeros((1, 5)) - 0.05
    out = np.asarray(gc.with_margin(g, 0.1, gc.CONSTRAINTS))[0]
    assert np.allclose(out, [0.05, -0.05, 0.05, 0.05, -0.05])  # endurance current slip drift falls
    present = ("endurance", "current", "slip", "falls")  # a turning gait: no drift column
    out = np.asarray(gc.with_margin(jnp.zeros((1, 4)), 0.2, present))[0]
    assert np.allclose(out, [0.2, 0.0, 0.2, 0.0])
    assert gc.with_margin(g, 0.0, gc.CONSTRAINTS) is g


def test_search_margin_acts_in_evaluate_not_in_report():
    base = make_gait_problem("nao", backend="native", horizon=1.0, constrained=True)
    tight = make_gait_problem("nao", backend="native", horizon=1.0, constrained=True, margin=0.3)
    x = jnp.asarray(np.stack([np.asarray(base.lower), np.asarray(base.upper)]) * 0.5
                    + 0.5 * np.asarray(base.lower))
    v0 = np.asarray(base.evaluate(x).violation)
    v1 = np.asarray(tight.evaluate(x).violation)
    _, _, g = base.constraints(jnp.clip(x, base.lower, base.upper))
    want = np.asarray(gc.violation(gc.with_margin(g, 0.3, base.constraint_names)))
    assert np.allclose(v1, want, atol=1e-6) and np.all(v1 > v0)
    assert tight.report(np.asarray(x[0]))["violation"] == pytest.approx(
        base.report(np.asarray(x[0]))["violation"], abs=1e-6)
    with pytest.raises(ProblemError, match="margin"):
        make_gait_problem("nao", backend="native", margin=0.1)
    with pytest.raises(ProblemError, match="margin"):
        make_gait_problem("nao", backend="native", constrained=True, margin=1.5)


def test_gait_table_of_a_turning_gait(tmp_path):
    """experiments/nao_gait_table.py on a stored turning gait: no drift constraint (turning is
    its objective), the turn rate reported, and ``--seed`` draws another run seed's stream."""
    import os
    import subprocess
    import sys

    gait = Path("experiments/results/nao_constrained_warp/turn_left/best_gait.json")
    out = tmp_path / "table.json"
    cmd = [sys.executable, "experiments/nao_gait_table.py", str(gait), "--worlds", "2",
           "--stream", "selection", "--seed", "100", "--out", str(out)]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                         env={**os.environ, "JAX_PLATFORMS": "cpu"})
    assert run.returncode == 0, run.stderr[-2000:]
    rec = json.loads(out.read_text())
    assert rec["turn"] == "left" and rec["seed"] == 100 and rec["stream"] == "selection"
    assert set(rec["constraints"]) == {"endurance", "current", "slip"}
    assert "drift" not in rec["walking_worlds_worst"]
    assert rec["turn_deg_s_mean"] > 1.0  # it turns left, as searched
