"""Heading feedback in the gait rollouts (:mod:`eaco_jax.gait.steer`): the controller by hand,
the turn-rate sensitivity against finite differences, real rollouts on both backends, the
refusals and the records of ``eaco gait`` / ``gait-eval``."""

from __future__ import annotations

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from eaco_jax.cli import app
from eaco_jax.errors import ProblemError
from eaco_jax.gait import steer as st
from eaco_jax.gait.steer import Steering
from eaco_jax.gait.walk_engine import PARAM_NAMES
from eaco_jax.gait.worlds import RobustConfig, stream_key
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.runs.gait import params_vector, read_params_file

GAIT = "experiments/results/nao_best_gait.json"
TURN = PARAM_NAMES.index("turn_rate")


def row(x=0.0, y=0.0, yaw=0.0, n=1):
    r = np.zeros((n, 7), np.float32)
    r[:, 0], r[:, 1], r[:, 6] = x, y, yaw
    return r


def test_update_by_hand():
    dt = 0.02
    cfg = Steering(gain=2.0, lookahead=math.inf, max_rate=10.0, tau=0.5)
    s0 = st.start_state(1, np)
    s1, c = st.update(s0, row(yaw=0.2), np.zeros((1, 2)), 0.0, cfg, dt, np)
    z = -0.2 * dt / (0.5 + dt)  # the low-pass's first step from 0
    assert np.allclose(s1.z, z, atol=1e-7) and np.allclose(c, 2.0 * z, atol=1e-7)
    assert np.allclose(s1.c_prev, c)  # the next step's "previous" correction
    # the line term: 0.5 m left of the x axis, lookahead 1 m, no filter
    cfg = Steering(gain=1.0, lookahead=1.0, max_rate=10.0, tau=0.0)
    _, c = st.update(s0, row(x=3.0, y=0.5, yaw=0.1), np.zeros((1, 2)), 0.0, cfg, dt, np)
    assert np.allclose(c, -0.1 - math.atan(0.5), atol=1e-6)
    # the desired direction 90 deg: the line is the y axis, "left" of it is -x
    _, c = st.update(s0, row(x=-0.5, y=3.0, yaw=0.0), np.zeros((1, 2)), math.pi / 2, cfg, dt,
                     np)
    assert np.allclose(c, -math.atan(0.5), atol=1e-6)
    # the clamp, and a heading past pi wraps to the short way round
    cfg = Steering(gain=5.0, max_rate=0.3, tau=0.0)
    _, c = st.update(s0, row(yaw=[-0.5, 3.5], n=2), np.zeros((2, 2)), 0.0, cfg, dt, np)
    assert np.allclose(c, [0.3, 0.3])  # 3.5 rad left is 2.78 rad right: turn left
    # numpy and jax agree
    _, cj = st.update(st.start_state(2), jnp.asarray(row(yaw=[-0.5, 3.5], n=2)),
                      jnp.zeros((2, 2)), 0.0, cfg, dt)
    assert np.allclose(np.asarray(cj), c)


def test_track_turn_by_hand():
    """``track_turn``: the heading to hold turns at the commanded rate (``turn_reference``),
    and the error to it wraps the short way round."""
    assert np.allclose(st.turn_reference(np.array([0.1, -0.2]), 50, 0.02), [0.1, -0.2])
    cfg = Steering(gain=1.0, max_rate=10.0, tau=0.0, track_turn=True)
    s0 = st.start_state(2, np)
    _, c = st.update(s0, row(yaw=[0.3, -2.7], n=2), np.zeros((2, 2)), 0.0, cfg, 0.02, np,
                     ref=np.array([0.5, 3.5]))
    # 0.2 rad short of the reference; 6.2 rad ahead of it is 0.083 rad behind the other way
    assert np.allclose(c, [0.2, 6.2 - 2 * math.pi], atol=1e-6)


def test_delayed_uses_the_previous_correction_in_late_worlds():
    c, prev = np.array([1.0, 2.0, 3.0]), np.array([-1.0, -2.0, -3.0])
    assert np.array_equal(st.delayed(c, prev, np.array([0, 1, 2])), [1.0, -2.0, -3.0])
    assert np.array_equal(np.asarray(st.delayed(jnp.asarray(c), jnp.asarray(prev),
                                                jnp.array([1, 0, 0]))), [-1.0, 2.0, 3.0])


def test_settings_are_checked_and_round_trip():
    for bad in (dict(gain=-1.0), dict(tau=float("nan")), dict(lookahead=0.0),
                dict(max_rate=float("inf"))):
        with pytest.raises(ProblemError, match="steering"):
            Steering(**bad)
    for cfg in (Steering(), Steering(gain=0.5, lookahead=2.0, max_rate=0.2, tau=0.25)):
        rec = json.loads(json.dumps(cfg.record()))
        assert Steering.from_record(rec) == cfg
    assert Steering().record()["lookahead"] is None
    assert Steering.from_record(None) is None
    with pytest.raises(ProblemError, match="steering must be"):
        Steering.from_record({"gain": 1.0, "kp": 2.0})
    # track_turn: kept by the record when on, absent (as before it existed) when off
    track = Steering(track_turn=True)
    assert Steering.from_record(json.loads(json.dumps(track.record()))) == track
    assert "track_turn" not in Steering().record()
    for bad in (dict(track_turn="yes"), dict(track_turn=True, lookahead=1.0)):
        with pytest.raises(ProblemError, match="track_turn"):
            Steering(**bad)
    with pytest.raises(ProblemError, match="track_turn"):
        Steering.from_record({"gain": 1.0, "track_turn": 1})


def test_turn_sensitivity_is_the_derivative_of_the_targets():
    p = make_gait_problem("nao", backend="native", horizon=2.0)
    x = p.gait_row(params_vector(read_params_file(GAIT), p, GAIT))
    u, d = (np.asarray(a) for a in st.turn_sensitivity(p.controls, x, TURN))
    assert np.array_equal(u, np.asarray(p.controls(x)))  # the targets from the same pass
    h = 1e-2
    fd = (np.asarray(p.controls(x.at[:, TURN].add(h)))
          - np.asarray(p.controls(x.at[:, TURN].add(-h)))) / (2 * h)
    assert np.abs(d).max() > 1e-2  # the turn rate moves the legs after the ramp
    assert np.allclose(d, fd, atol=2e-3)


def test_first_order_targets_at_the_clamp_stay_within_a_quarter_encoder_count():
    """What steer.py's docstring promises, on the margin-searched constrained gait."""
    path = "experiments/results/nao_steer_margin_gpu/best_gait.json"
    p = make_gait_problem("nao", backend="native", horizon=4.0)
    x = p.gait_row(params_vector(read_params_file(path), p, path))
    u0, d = (np.asarray(a) for a in st.turn_sensitivity(p.controls, x, TURN))
    clamp = Steering().max_rate
    for c in (clamp, -clamp):
        exact = np.asarray(p.controls(x.at[:, TURN].add(c)))
        assert np.abs(exact - (u0 + c * d)).max() < 0.25 * 2 * math.pi / 4096


def _problem(backend, steering, horizon=4.0, robust=None):
    return make_gait_problem("nao", backend=backend, horizon=horizon, steering=steering,
                             robust=robust)


def _gaits(p):
    v = np.asarray(params_vector(read_params_file(GAIT), p, GAIT)).copy()
    v[TURN] = 0.15  # a gait that turns left by itself
    return p.gait_row(v)


def test_native_feedback_holds_the_heading_and_off_is_open_loop():
    open_p = _problem("native", None)
    x = _gaits(open_p)
    trace0 = np.asarray(open_p.trace(x))
    assert trace0[0, -1, 6] > 0.25  # open loop: turned more than 14 degrees in 4 s
    zero = np.asarray(_problem("native", Steering(gain=0.0)).trace(x))
    assert np.array_equal(zero, trace0)  # no gain: exactly the open-loop walk
    held = np.asarray(_problem("native", Steering()).trace(x))
    assert abs(held[0, -1, 6]) < 0.5 * trace0[0, -1, 6]
    assert not bool(open_p.summarize(jnp.asarray(held)).fell[0])


def test_native_feedback_in_worlds_reduces_the_spread_of_drift():
    cfg = RobustConfig(R=6, seed=3)
    out = {}
    for name, steering in (("open", None), ("held", Steering())):
        p = _problem("native", steering, horizon=6.0, robust=cfg)
        x = p.gait_row(params_vector(read_params_file(GAIT), p, GAIT))
        tr = np.asarray(p._rollout(x, p.worlds(stream_key(3, "test", 0), 6), False)["trace"])
        out[name] = tr[:, -1, 6]
    assert np.std(out["held"]) < 0.6 * np.std(out["open"])


def test_native_track_turn_turns_at_the_commanded_rate_and_at_zero_holds_the_heading():
    """Two gaits asked to turn at 0.15 and -0.1 rad/s, each in six randomised worlds (rollout
    ``a * R + r``): open loop the first ends anywhere from 0.2 to 0.7 rad; tracking its turn
    brings every world of each gait within 0.3 rad of its own rate x 6 s and narrows the
    spread. At turn rate 0 tracking is heading hold, bit for bit."""
    cfg = RobustConfig(R=6, seed=3)
    end = {}
    for name, steering in (("open", None), ("track", Steering(track_turn=True))):
        p = _problem("native", steering, horizon=6.0, robust=cfg)
        x = _gaits(p)
        x = jnp.concatenate([x, x.at[:, TURN].set(-0.1)])
        tr = np.asarray(p._rollout(x, p.worlds(stream_key(3, "test", 0), 6), False)["trace"])
        end[name] = np.unwrap(tr[:, :, 6], axis=1)[:, -1].reshape(2, 6)
    want = np.array([[0.15 * 6.0], [-0.1 * 6.0]])
    assert np.max(np.abs(end["track"] - want)) < 0.3 < np.max(np.abs(end["open"] - want))
    assert np.std(end["track"][0]) < 0.5 * np.std(end["open"][0])
    x0 = _gaits(_problem("native", None)).at[:, TURN].set(0.0)
    held = np.asarray(_problem("native", Steering()).trace(x0))
    assert np.array_equal(np.asarray(_problem("native", Steering(track_turn=True)).trace(x0)),
                          held)


@pytest.mark.slow
def test_mjx_feedback_matches_native():
    """Over 2 s (beyond, a foot impact can amplify float32 differences through the loop:
    4 s leave up to 0.012 rad of heading between the backends, open loop 3e-5)."""
    x = _gaits(_problem("native", None))
    for steering in (Steering(), Steering(lookahead=1.0)):
        nat = np.asarray(_problem("native", steering, horizon=2.0).trace(x))
        mjx = np.asarray(jax.jit(_problem("mjx", steering, horizon=2.0).trace)(x))
        assert abs(nat[0, -1, 6] - np.asarray(_problem("native", None, 2.0).trace(x))[0, -1, 6]
                   ) > 0.03  # the loop acted
        assert np.allclose(nat[0, :, :3], mjx[0, :, :3], atol=2e-3)
        assert np.allclose(nat[0, :, 6], mjx[0, :, 6], atol=2e-3)
    # two gaits tracking their own turns, in two randomised worlds each (per-rollout rates)
    cfg = RobustConfig(R=2, seed=3)
    p_nat = _problem("native", Steering(track_turn=True), horizon=2.0, robust=cfg)
    p_mjx = _problem("mjx", Steering(track_turn=True), horizon=2.0, robust=cfg)
    x = _gaits(p_nat)
    x = jnp.concatenate([x.at[:, TURN].set(0.25), x.at[:, TURN].set(-0.1)])
    w = p_nat.worlds(stream_key(3, "test", 0), 2)
    nat = np.asarray(p_nat._rollout(x, w, False)["trace"])
    mjx = np.asarray(jax.jit(lambda x: p_mjx._rollout(x, w, False)["trace"])(x))
    # over the first 1.5 s: a foot impact near 2 s amplifies float32 differences in one world
    assert np.allclose(nat[:, :76, 6], mjx[:, :76, 6], atol=2e-3)


def test_refusals():
    with pytest.raises(ProblemError, match="biped"):
        make_gait_problem("ant", backend="native", steering=Steering())
    with pytest.raises(ProblemError, match="turning gait"):
        make_gait_problem("nao", backend="native", turn="left", steering=Steering())
    assert make_gait_problem("nao", backend="native", turn="left",
                             steering=Steering(track_turn=True)).steering.track_turn
    from eaco_jax.problems.gait_library import make_gait_library_problem

    with pytest.raises(ProblemError, match="track_turn"):
        make_gait_library_problem(backend="native", steering=Steering())
    lib = make_gait_library_problem(backend="native", steering=Steering(track_turn=True))
    assert lib.gait.steering.track_turn
    with pytest.raises(ValueError, match="track_turn needs steer.rates"):
        from eaco_jax.gait.rollout_native import native_rollout

        p = _problem("native", None, horizon=0.1)
        u, d = st.turn_sensitivity(p.controls, _gaits(p), TURN)
        native_rollout(np.asarray(u), p.spec, steer=st.SteerInputs(
            np.asarray(d), Steering(track_turn=True), 0.0))
    with pytest.raises(ProblemError, match="a Steering"):
        make_gait_problem("nao", backend="native", steering={"gain": 1.0})


def _invoke(args):
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, (res.output, res.exception)
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_gait_and_gait_eval_record_steering_and_noise(tmp_path):
    out = tmp_path / "run"
    rec = _invoke(["gait", "--backend", "native", "--ants", "4", "--iterations", "1",
                   "--horizon", "1.5", "--robust", "2", "--steer", "--target-noise", "0.0004",
                   "--trials", "3", "--json", "--out", str(out), "--no-video"])
    assert rec["steering"] == Steering().record()
    assert rec["robust"]["target_noise"] == pytest.approx(0.0004)
    assert rec["trials"]["target_noise"] == pytest.approx(0.0004)
    ev = _invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native",
                  "--trials", "3", "--json"])
    assert ev["steering"] == Steering().record()  # from the file
    assert ev["trials"]["target_noise"] == pytest.approx(0.0004)
    assert ev["trials"]["falls"] == rec["trials"]["falls"]
    assert ev["trials"]["speed_mps_mean"] == pytest.approx(rec["trials"]["speed_mps_mean"],
                                                           abs=1e-6)
    off = _invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native",
                   "--no-steer", "--target-noise", "0.005", "--json"])
    assert "steering" not in off
    res = CliRunner().invoke(app, ["gait", "--target-noise", "-1"])
    assert res.exit_code != 0 and "target_noise must be" in res.output


def test_eaco_gait_tracks_a_turning_gaits_turn_with_track_turn(tmp_path):
    out = tmp_path / "turn"
    rec = _invoke(["gait", "--backend", "native", "--ants", "4", "--iterations", "1",
                   "--horizon", "1.0", "--turn", "left", "--steer", "--track-turn", "--json",
                   "--out", str(out), "--no-video"])
    assert rec["steering"] == Steering(track_turn=True).record()
    ev = _invoke(["gait-eval", str(out / "best_gait.json"), "--backend", "native", "--json"])
    assert ev["steering"]["track_turn"] is True  # the file's steering, tracking included
    res = CliRunner().invoke(app, ["gait", "--track-turn"])
    assert res.exit_code != 0 and "--track-turn needs --steer" in res.output
    res = CliRunner().invoke(app, ["gait", "--turn", "left", "--steer", "--backend", "native",
                                   "--ants", "4", "--iterations", "1"])
    assert res.exit_code != 0 and "--track-turn" in res.output
