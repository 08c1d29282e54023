"""The steered gait problem: commands from the controller's rule, per-world schedules that
blend, the pairing of ants and worlds, the fall cost, the refusals."""

from __future__ import annotations

import dataclasses
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.errors import ProblemError
from eaco_jax.gait import walk_route as wr
from eaco_jax.gait.worlds import RobustConfig, stream_key
from eaco_jax.problems.gait import make_gait_problem
from eaco_jax.problems.gait_steer import (
    STEP,
    TURN,
    SteerConfig,
    command_of,
    make_steered_problem,
    steered_params,
    world_commands,
)


def _forward() -> np.ndarray:
    gaits = wr.load_walk_gaits("nao")
    return np.asarray(gaits.forward, np.float32)


def test_defaults_are_the_controllers():
    ctrl, steer = wr.Controller(), SteerConfig()
    for name in ("steer_gain", "max_steer", "slow_deg", "stop_deg", "min_step", "blend_cycles"):
        assert getattr(steer, name) == getattr(ctrl, name), name


def test_command_of_is_the_controllers_rule():
    cfg, ctrl = SteerConfig(), wr.Controller()
    errors = np.radians(np.linspace(-89.0, 89.0, 41))
    turn, step = command_of(jnp.asarray(errors, jnp.float32), cfg)
    for e, t, s in zip(errors, np.asarray(turn), np.asarray(step), strict=True):
        choice = wr.choose(float(e), wr.FORWARD, ctrl)
        assert t == pytest.approx(choice.steer, abs=1e-5)
        assert s == pytest.approx(choice.step, abs=1e-5)


def test_schedule_segments_and_blend():
    p = jnp.asarray(_forward())
    period = float(p[3])
    turn = jnp.array([0.2, -0.6, 0.8])
    step = jnp.array([1.0, 0.5, 0.35])
    horizon, blend = 6.0, 0.5
    times = jnp.arange(600, dtype=jnp.float32) * 0.01
    pt = np.asarray(steered_params(p, turn, step, times, horizon, blend))
    at = lambda t: pt[int(round(t / 0.01))]  # noqa: E731
    assert at(1.0)[TURN] == pytest.approx(0.2)
    assert at(1.0)[STEP] == pytest.approx(float(p[STEP]))
    mid = 2.0 + 0.5 * blend * period  # halfway through the blend into segment 1
    assert at(mid)[TURN] == pytest.approx(0.5 * (0.2 - 0.6), abs=0.03)
    assert at(2.0 + blend * period + 0.02)[TURN] == pytest.approx(-0.6)
    assert at(5.9)[STEP] == pytest.approx(0.35 * float(p[STEP]))
    others = [i for i in range(pt.shape[1]) if i not in (TURN, STEP)]
    np.testing.assert_array_equal(pt[:, others], np.broadcast_to(np.asarray(p)[others],
                                                                   (600, len(others))))
    # the turn never jumps between control steps: every change is a blend
    assert np.max(np.abs(np.diff(pt[:, TURN]))) < 1.05 * 1.4 / (blend * period / 0.01)


def test_commands_come_from_the_worlds_key():
    prob = make_steered_problem("nao", backend="native", horizon=2.0,
                                robust=RobustConfig(R=64, seed=0),
                                steer=SteerConfig(stop_deg=60.0))  # errors reach the floor
    cfg = prob.steer
    a = world_commands(prob.worlds(stream_key(0, "optimisation", 3)), cfg)
    b = world_commands(prob.worlds(stream_key(0, "optimisation", 3)), cfg)
    c = world_commands(prob.worlds(stream_key(0, "optimisation", 4)), cfg)
    np.testing.assert_array_equal(np.asarray(a[0]), np.asarray(b[0]))
    assert not np.allclose(np.asarray(a[0]), np.asarray(c[0]))
    turn, step = (np.asarray(x) for x in a)
    assert turn.shape == (64, cfg.segments)
    assert np.all(np.abs(turn) <= cfg.max_steer + 1e-6) and np.any(turn > 0.7)
    assert np.all((step >= cfg.min_step - 1e-6) & (step <= 1.0)) and np.any(step < 0.4)


def test_ants_stay_in_their_worlds():
    """With one command equal to the gait's own and no target noise, every (ant, world)
    rollout of the steered problem is the plain problem's rollout of that ant in that world:
    the per-world batching keeps ants and worlds paired as the plain problem does."""
    base = _forward()
    base[TURN] = 0.0
    x = jnp.asarray(np.stack([base, base * np.where(np.arange(base.size) == 1, 0.97, 1.0)]))
    robust = RobustConfig(R=3, seed=0, target_noise=0.0)
    steer = SteerConfig(segments=2, steer_gain=1e-9, min_step=1.0)
    prob = make_steered_problem("nao", backend="native", horizon=1.6, robust=robust,
                                steer=steer, walker_physics=False)
    plain = make_gait_problem("nao", backend="native", horizon=1.6, robust=robust)
    worlds = prob.worlds(stream_key(0, "optimisation", 1))
    got = np.asarray(jax.jit(prob.steered_trace)(x, worlds))
    want = np.asarray(jax.jit(lambda x, w: plain._rollout(x, w, False)["trace"])(x, worlds))
    np.testing.assert_allclose(got, want, atol=1e-4)
    assert not np.allclose(got[0], got[1], atol=1e-3)  # worlds differ, so pairing is seen
    # the walker's physics (servos, held targets) is another simulation than the spec's
    walker = prob.replace(walker_physics=True)
    other = np.asarray(jax.jit(walker.steered_trace)(x, worlds))
    assert np.all(np.isfinite(other)) and np.max(np.abs(other - got)) > 1e-3


def test_a_fall_costs_more_than_any_progress():
    robust = RobustConfig(R=2, seed=0, push=40.0)  # a push no gait stands
    prob = make_steered_problem("nao", backend="native", horizon=2.5, robust=robust)
    res = jax.tree.map(np.asarray, jax.jit(lambda x: prob.rollout(x, prob.worlds()))(
        jnp.asarray(_forward()[None])))
    assert res["fell"].all()
    np.testing.assert_allclose(res["fitness"], res["distance_m"] - prob.fall_cost, atol=1e-5)
    assert prob.fall_cost == pytest.approx(5.0)
    assert np.all(res["fitness"] < 0)


def test_refusals():
    with pytest.raises(ProblemError, match="robust"):
        make_steered_problem("nao", backend="native")
    with pytest.raises(ProblemError, match="turn"):
        make_steered_problem("nao", backend="native", turn="left", robust=RobustConfig())
    with pytest.raises(ProblemError, match="biped"):
        make_steered_problem("ant", backend="native", robust=RobustConfig())
    with pytest.raises(ProblemError, match="segments"):
        SteerConfig(segments=0)
    with pytest.raises(ProblemError, match="min_step"):
        SteerConfig(min_step=0.0)
    with pytest.raises(ProblemError, match="slow_deg"):
        SteerConfig(slow_deg=130.0)
    with pytest.raises(ProblemError, match="steer must be a SteerConfig"):
        make_steered_problem("nao", backend="native", robust=RobustConfig(), steer={})
    prob = make_steered_problem("nao", backend="native", robust=RobustConfig(R=1))
    with pytest.raises(ProblemError, match="quality"):
        prob.rollout(jnp.asarray(_forward()[None]), prob.worlds(), quality=True)
    assert dataclasses.replace(SteerConfig(), error_deg=30.0).error_deg == 30.0
    assert math.isfinite(json.loads(json.dumps(dataclasses.asdict(SteerConfig())))["error_deg"])
