"""Robust fitness: randomised worlds are reproducible and enter both backends the same way, a
colony is evaluated as ants x R in one call and aggregated; validation trials and the exported
run (replayed with plain mujoco, no eaco code)."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from eaco_jax.gait import walk_engine as we
from eaco_jax.gait.fitness import aggregate
from eaco_jax.gait.rollout_mjx import _world_model, mjx_model
from eaco_jax.gait.rollout_native import native_model, native_rollout
from eaco_jax.gait.validate import TRIAL_STREAM, evaluate_trials, export_run
from eaco_jax.gait.worlds import (
    VARIED_FIELDS,
    RobustConfig,
    actuated_dofs,
    couple_controls,
    friction_geom_ids,
    model_fields,
    native_world_models,
    push_at,
    world_ctrl_at,
    world_key,
)
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.gait import make_gait_problem


def _gait(**kw):
    g = dict(step_length=0.06, hip_height=0.21, duty_ratio=0.6, period=0.5, foot_lift=0.02,
             step_width=0.01, lateral_sway=0.02, torso_pitch=0.05, arm_swing=0.3,
             hip_roll_comp=0.0, ankle_pitch_comp=0.0, ankle_roll_comp=0.0, direction=0.0,
             turn_rate=0.0)
    g.update(kw)
    return [g[n] for n in we.PARAM_NAMES]


@pytest.fixture(scope="module")
def problem():
    return make_gait_problem("nao", backend="native", horizon=1.0, robust=RobustConfig(R=3))


def test_config_errors():
    for bad in (dict(R=0), dict(aggregate="median"), dict(alpha=0.0), dict(friction=(1.0, 0.5)),
                dict(mass=1.5), dict(latency=-1), dict(push=-1.0), dict(target_noise=float("nan"))):
        with pytest.raises(ProblemError, match="robust"):
            RobustConfig(**bad)
    with pytest.raises(ProblemError, match="RobustConfig"):
        make_gait_problem("nao", backend="native", robust={"R": 8})
    # without a motor datasheet the worlds vary all but the motors (tests/test_robot_gaits.py)
    assert make_gait_problem("ant", backend="native", robust=RobustConfig()).robust is not None


def test_worlds_are_reproducible_and_within_ranges(problem):
    spec, cfg = problem.spec, RobustConfig(R=16, push=1.0)
    p = problem.replace(robust=cfg, horizon=4.0)
    a, b = p.worlds(world_key(3, 7)), p.worlds(world_key(3, 7))
    c = p.worlds(world_key(3, 8))
    for f in ("friction", "mass_scale", "stall_scale", "latency", "init_dq", "push_force"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert not np.allclose(a.friction, c.friction)
    assert not np.allclose(p.worlds(world_key(3, 7, TRIAL_STREAM)).friction, a.friction)
    assert np.all((a.friction >= 0.5) & (a.friction <= 1.0))
    assert np.all(np.abs(a.stall_scale - 1) <= 0.08 + 1e-6)
    assert np.all(np.abs(a.speed_scale - 1) <= 0.10 + 1e-6)
    assert np.all(np.abs(a.mass_scale - 1) <= 0.10 + 1e-6) and np.all(a.mass_scale[:, 0] == 1)
    assert set(np.asarray(a.latency).tolist()) <= {0, 1}
    li, ri = spec.joint_names.index("LHipYawPitch"), spec.joint_names.index("RHipYawPitch")
    for f in ("stall_scale", "speed_scale", "init_dq"):  # one motor for the pair
        np.testing.assert_array_equal(getattr(a, f)[:, li], getattr(a, f)[:, ri])
    impulse = np.linalg.norm(a.push_force, axis=1) * 0.1
    assert np.all((impulse >= 0.5 - 1e-5) & (impulse <= 1.0 + 1e-5))
    assert np.all(a.push_start >= int(1.0 / spec.control_dt))  # after the start-up ramp
    assert np.all(a.push_stop == a.push_start + 5) and np.all(a.push_stop <= p.n_steps)


def test_targets_get_latency_and_noise(problem):
    spec = problem.spec
    controls = jnp.cumsum(jnp.ones((2, 30, spec.nu), jnp.float32) * 0.01, axis=1)  # ramps
    w = problem.worlds(world_key(0, 0)).replace(latency=jnp.array([0, 1, 2], jnp.int32))
    quiet = w.replace(noise_std=jnp.zeros(()))
    u = np.asarray(world_ctrl_at(controls, jnp.int32(10), quiet, spec))  # (A, R, nu)
    for r, lag in enumerate((0, 1, 2)):
        np.testing.assert_allclose(u[:, r], np.asarray(controls[:, 10 - lag]), rtol=1e-6)
    noisy = np.stack([np.asarray(world_ctrl_at(controls, jnp.int32(t), w, spec))
                      for t in range(5, 30)])
    clean = np.stack([np.asarray(world_ctrl_at(controls, jnp.int32(t), quiet, spec))
                      for t in range(5, 30)])
    assert np.std(noisy - clean) == pytest.approx(0.005, rel=0.15)
    li, ri = spec.joint_names.index("LHipYawPitch"), spec.joint_names.index("RHipYawPitch")
    np.testing.assert_array_equal(noisy[..., li], noisy[..., ri])
    # each world's push acts from its start step (inclusive) to its stop step (exclusive)
    np.testing.assert_allclose(np.asarray(push_at(w.push_start, w)), w.push_force)
    assert not np.any(np.asarray(push_at(w.push_stop, w)))


def test_model_fields_are_the_same_on_both_backends(problem):
    spec = problem.spec
    model = native_model(spec, 0.0, "fast")
    w = problem.worlds(world_key(1, 2))
    natives = native_world_models(model, spec, jax.tree.map(np.asarray, w))
    mm = mjx_model(spec, 0.0, "fast")
    base = {f: getattr(mm, f) for f in VARIED_FIELDS}
    fields = model_fields(base, w, friction_geom_ids(model, spec), actuated_dofs(model, spec))
    batched, axes = _world_model(mm, fields, jnp.arange(3))
    floor, knee = model.geom("floor").id, spec.joint_names.index("LKneePitch")
    for r, m in enumerate(natives):
        for f in VARIED_FIELDS:
            np.testing.assert_allclose(np.asarray(getattr(batched, f))[r], getattr(m, f),
                                       rtol=1e-5, err_msg=f)
        assert m.geom_friction[floor, 0] == pytest.approx(float(w.friction[r]), rel=1e-6)
        assert m.geom_friction[model.geom("l_sole_fl").id, 0] == m.geom_friction[floor, 0]
        assert m.actuator_forcerange[knee, 1] == pytest.approx(
            model.actuator_forcerange[knee, 1] * float(w.stall_scale[r, knee]), rel=1e-6)
        dof = model.joint("LKneePitch").dofadr[0]
        assert m.dof_damping[dof] == pytest.approx(
            model.dof_damping[dof] * float(w.stall_scale[r, knee] / w.speed_scale[r, knee]),
            rel=1e-5)
    assert model.geom_friction[floor, 0] == 1.0  # the base model is untouched
    assert axes.body_mass == 0 and axes.geom_size is None


def test_robust_evaluate_is_one_batched_call_and_aggregates(problem):
    x = jnp.asarray([_gait(), _gait(step_length=0.03)], jnp.float32)
    calls = []
    import eaco_jax.gait.rollout_native as rn

    original = rn.native_rollout

    def counting(controls, *a, **kw):
        calls.append(controls.shape)
        return original(controls, *a, **kw)

    rn.native_rollout = counting
    try:
        per_world = problem.rollout(x, problem.worlds())
        ev = jax.jit(problem.evaluate)(x)
        ev2 = problem.evaluate(x, world_key(0, 5))
    finally:
        rn.native_rollout = original
    assert calls and all(c[0] == 2 * 3 for c in calls)  # ants x R in one rollout call
    assert per_world["fitness"].shape == (2, 3)
    expected = aggregate(per_world["fitness"], "cvar", 0.25)  # ceil(0.25 * 3) = 1: the worst
    np.testing.assert_allclose(-np.asarray(ev.f), np.asarray(expected), rtol=1e-4)  # jit vs not
    np.testing.assert_allclose(np.asarray(expected), np.min(per_world["fitness"], 1), rtol=1e-6)
    assert not np.allclose(np.asarray(ev.f), np.asarray(ev2.f))  # another key, other worlds
    np.testing.assert_array_equal(np.asarray(ev.f), np.asarray(jax.jit(problem.evaluate)(x).f))
    f = jnp.asarray([[1.0, 2.0, 3.0, 4.0]])
    assert float(aggregate(f, "mean")[0]) == 2.5 and float(aggregate(f, "worst")[0]) == 1.0
    assert float(aggregate(f, "cvar", 0.5)[0]) == 1.5


def test_robust_worlds_agree_across_backends(problem):
    """The same worlds on MJX and native: during the 1 s start-up the torso paths agree to 5 mm
    (float32 vs float64; longer, chaotic runs agree in distribution, not path by path)."""
    x = jnp.asarray([_gait()], jnp.float32)
    w = problem.worlds(world_key(2, 0))
    runs = {b: jax.jit(lambda x, w, b=b: problem.replace(backend=b)._rollout(x, w, True))(x, w)
            for b in ("native", "mjx")}
    n, m = runs["native"], runs["mjx"]
    assert n["trace"].shape == m["trace"].shape == (3, 51, 7)
    np.testing.assert_allclose(np.asarray(m["trace"])[..., :3], np.asarray(n["trace"])[..., :3],
                               atol=5e-3)
    np.testing.assert_allclose(np.asarray(m["acc"]["energy"]), np.asarray(n["acc"]["energy"]),
                               rtol=0.03)
    # the worlds differ from each other (masses, motors, initial pose)
    assert np.ptp(np.asarray(n["trace"])[:, -1, 2]) > 1e-4


def test_trials_and_accurate():
    p = make_gait_problem("nao", backend="native", horizon=2.0)
    tr = evaluate_trials(p, _gait(), n=6, seed=1)
    assert set(tr) >= {"n", "falls", "speed_mps_mean", "speed_mps_ci95",
                       "cost_of_transport_mean"}
    assert tr["n"] == 6 and tr["falls"] == 0 and tr["accuracy"] == "fast"
    assert tr["fall_trials"] == []
    assert 0.05 < tr["speed_mps_mean"] < 0.3 and 0 < tr["speed_mps_ci95"] < 0.05
    assert tr == evaluate_trials(p, _gait(), n=6, seed=1)  # reproducible
    assert tr != evaluate_trials(p, _gait(), n=6, seed=2)
    acc = evaluate_trials(p, _gait(), n=2, seed=1, accurate=True)
    assert acc["accuracy"] == "accurate" and acc["falls"] == 0
    assert acc["speed_mps_mean"] == pytest.approx(tr["speed_mps_mean"], abs=0.05)
    with pytest.raises(ProblemError, match="trials"):
        evaluate_trials(p, _gait(), n=0)


def test_trials_name_the_worlds_that_fell():
    """Shoves far beyond the defaults topple some trials: the record names which ones."""
    p = make_gait_problem("nao", backend="native", horizon=2.0)
    tr = evaluate_trials(p, _gait(), n=6, seed=1, config=RobustConfig(push=12.0))
    assert 0 < tr["falls"] == len(tr["fall_trials"])
    assert all(0 <= i < 6 for i in tr["fall_trials"])
    assert tr["fall_trials"] == sorted(set(tr["fall_trials"]))


def test_export_replays_on_plain_mujoco(tmp_path):
    p = make_gait_problem("nao", backend="native", horizon=2.0, slope_deg=3.0)
    path = export_run(p, _gait(), tmp_path / "run.npz")
    run = np.load(path)
    t = int(round(2.0 / 0.02))
    assert run["ctrl"].shape == (t, 22) and run["qpos"].shape == (t + 1, 29)
    assert run["qvel"].shape == (t + 1, 28) and float(run["control_dt"]) == 0.02
    m = mujoco.MjModel.from_xml_string(str(run["model_xml"]))
    assert m.opt.timestep * int(run["substeps"]) == pytest.approx(0.02)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = run["qpos"][0], run["qvel"][0]
    mujoco.mj_kinematics(m, d)
    floor_z = d.geom_xmat[m.geom("floor").id].reshape(3, 3)[:, 2]
    assert np.degrees(np.arccos(floor_z[2])) == pytest.approx(3.0, abs=1e-3)  # slope inside
    rows = [d.qpos.copy()]
    for u in run["ctrl"]:
        d.ctrl[:] = u
        mujoco.mj_step(m, d, nstep=int(run["substeps"]))
        rows.append(d.qpos.copy())
    np.testing.assert_allclose(np.array(rows), run["qpos"], atol=1e-9)
    assert run["qpos"][-1, 0] - run["qpos"][0, 0] > 0.1  # the exported run walks
    # and it is the run eaco simulates without the motor limits and with targets held per
    # control step (plain MuJoCo replays one control per step)
    assert not bool(run["limits_in_physics"])
    ctrl = couple_controls(np.asarray(p.controls(jnp.asarray([_gait()], jnp.float32))), p.spec,
                           xp=np)
    trace = native_rollout(ctrl, p.spec, p.slope_deg, limits=False,
                           interpolate=False)["trace"][0]
    np.testing.assert_allclose(run["qpos"][:, :3], trace[:, :3], atol=2e-3)


def test_search_draws_fresh_worlds_each_iteration_reproducibly():
    """A robust problem is stochastic: the driver hands evaluate a key per iteration (fresh
    worlds), and the same seed gives the same run."""
    import eaco_jax as ea
    from eaco_jax.gait.worlds import RobustConfig
    from eaco_jax.problems.gait import make_gait_problem
    from eaco_jax.strategies import ContinuousEACO

    p = make_gait_problem("nao", backend="native", horizon=0.2, robust=RobustConfig(R=2))
    assert p.stochastic
    fixed = p.replace(robust=RobustConfig(R=2, resample=False))
    assert not fixed.stochastic
    s = ContinuousEACO(num_ants=3, archive_size=3, refine_ants=0, repair_steps=0)
    a = ea.minimize(p, s, seed=4, iterations=2, chunk_size=2)
    b = ea.minimize(p, s, seed=4, iterations=2, chunk_size=2)
    np.testing.assert_array_equal(a.history["iter_mean_cost"], b.history["iter_mean_cost"])
    # two keys, two sets of worlds: a gait that walks (a second is long enough to move with
    # the targets interpolated between control steps) scores differently in them
    walk = p.replace(horizon=1.0)
    x = jnp.asarray([_gait()] * 3, jnp.float32)
    k1, k2 = jax.random.split(jax.random.key(0))
    assert not np.array_equal(np.asarray(walk.evaluate(x, k1).f),
                              np.asarray(walk.evaluate(x, k2).f))


def test_every_randomisation_range_names_its_source_or_says_it_is_an_assumption():
    """Issue 30 item 1: each range of the worlds carries its source, or is a documented
    assumption; a range added to RobustConfig without one fails here."""
    import dataclasses

    from eaco_jax.gait.worlds import RANGE_SOURCES, RobustConfig

    control = {"R", "aggregate", "alpha", "seed", "resample"}
    ranges = {f.name for f in dataclasses.fields(RobustConfig)} - control
    assert ranges == set(RANGE_SOURCES)
    for name, (kind, text) in RANGE_SOURCES.items():
        assert kind in ("sourced", "assumption"), name
        assert len(text) > 20, name


def test_joint_play_offsets_targets_by_a_constant_per_world_and_leaves_other_draws_alone(problem):
    """``RobustConfig.joint_play``: each world holds one target offset per joint, U(-play,
    play), the same at every control step, a coupled follower's equal to its leader's; off (0)
    the worlds and their commanded targets are those drawn before joint play existed."""
    from eaco_jax.gait import walk_route, walk_route_mjx

    spec = problem.spec
    w0 = problem.worlds(world_key(3, 7))
    # values of the code before joint_play (0c64c39..3dbd7ef): stored worlds stay reproducible
    np.testing.assert_allclose(np.asarray(w0.friction), [0.98645633, 0.82291532, 0.75864935],
                               rtol=1e-6)
    ctrl = jnp.zeros((2, 10, spec.nu))
    assert float(jnp.sum(world_ctrl_at(ctrl, jnp.int32(4), w0, spec))) == pytest.approx(
        0.07237160205841064, rel=1e-5)
    assert not np.any(np.asarray(w0.target_offset))
    play = 0.02
    p = problem.replace(robust=RobustConfig(R=3, joint_play=play))
    w = p.worlds(world_key(3, 7))
    for f in ("friction", "mass_scale", "stall_scale", "latency", "init_dq", "push_force"):
        np.testing.assert_array_equal(getattr(w, f), getattr(w0, f))
    off = np.asarray(w.target_offset)
    assert off.shape == (3, spec.nu) and np.all(np.abs(off) <= play)
    assert np.std(off) > play / 4  # spread over the range, not a constant
    for lead, follow in spec.coupled_joints:
        li, fi = spec.joint_names.index(lead), spec.joint_names.index(follow)
        np.testing.assert_array_equal(off[:, fi], off[:, li])
    ctrl = jax.random.normal(jax.random.PRNGKey(0), (2, 10, spec.nu)) * 0.1
    for t in (0, 3, 9):
        d = world_ctrl_at(ctrl, jnp.int32(t), w, spec) - world_ctrl_at(ctrl, jnp.int32(t), w0, spec)
        np.testing.assert_allclose(np.asarray(d), np.broadcast_to(off, d.shape), atol=1e-6)
    cfg = RobustConfig(joint_play=play)
    with pytest.raises(ProblemError, match="joint_play"):
        walk_route.sample_walk_worlds(None, spec, 2, 10, 5, cfg=cfg)
    with pytest.raises(ProblemError, match="joint_play"):
        walk_route_mjx.world_batch(None, spec, 2, 5, (0.0, 0.0), 0.0, cfg=cfg)
    with pytest.raises(ProblemError, match="joint_play"):
        RobustConfig(joint_play=-0.01)
