"""Route walking on MJX (issue #32, item 4): the analytic obstacle distances against MuJoCo's
``mj_geomDistance``, the JAX controller against the native one, a short walk against the
native walker, the batched walk against the unbatched one, and a walk into an obstacle."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from eaco_jax.gait import scene_world as sw
from eaco_jax.gait import walk_route as wr
from eaco_jax.gait import walk_route_mjx as wm
from eaco_jax.gait.robot import load_robot
from eaco_jax.problems.scenes import Obstacle, Scene

BOX = ((1.5, -0.6), (2.0, -0.6), (2.0, 0.6), (1.5, 0.6))  # a rectangle: a box geom
PENTAGON = ((0.55, 0.35), (0.95, 0.5), (1.0, 0.9), (0.7, 1.1), (0.45, 0.8))  # a mesh geom
TINY = Scene(name="tiny", bounds=(0.0, -2.0, 4.0, 2.0), start=(0.3, 0.0), goal=(3.3, 0.0),
             obstacles=(Obstacle(BOX, 0.5),))
AROUND = np.array([[0.3, 0.0], [1.3, -0.95], [2.2, -0.95], [3.3, 0.0]])  # around the box
THROUGH = np.array([[0.3, 0.0], [0.9, 0.0], [1.4, 0.0], [3.3, 0.0]])  # into it
WALK_TIME = 3.0  # s: three decisions steer the first corner

#: torso path MJX (float32) vs native (float64) on the same model and controller: measured
#: under 1e-5 m over WALK_TIME (a nominal walk, no contact events); 1 mm is a hundredth of a
#: step's length and still fails for one control step's shift of any decision
PATH_TOL = 1e-3


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


# --------------------------------------------------------------------------- geometry
def _random_poses(model, rng, n):
    """Robot poses near the obstacles: positions, yaw, height and joints drawn at random."""
    data = mujoco.MjData(model)
    for _ in range(n):
        data.qpos[:] = model.qpos0
        data.qpos[:2] = rng.uniform([0.2, -0.3], [2.3, 1.4])
        data.qpos[2] = rng.uniform(0.2, 0.9)  # from the soles on the floor to above the top
        yaw = rng.uniform(-math.pi, math.pi)
        data.qpos[3:7] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        data.qpos[7:] = model.qpos0[7:] + rng.normal(0.0, 0.5, model.nq - 7)
        mujoco.mj_forward(model, data)
        yield data


def test_obstacle_distances_are_mujocos_geom_distances(nao):
    scene = Scene(name="g", bounds=(0.0, -1.0, 3.0, 2.0), start=(0.0, 0.0), goal=(2.8, 1.8),
                  obstacles=(Obstacle(BOX, 0.5), Obstacle(PENTAGON, 0.3)))
    model = sw.scene_model(scene, nao)
    robot, obst = sw.robot_geom_ids(model), sw.geom_ids(model, "obstacle")
    geoms, prisms = wm._RobotGeoms.of(model), wm._Prisms.of(scene.obstacles)
    fn = jax.jit(lambda xp, xm: wm.obstacle_distances(xp, xm, geoms, prisms, 1.0))
    apart = touching = 0
    for data in _random_poses(model, np.random.default_rng(0), 150):
        native = sw.obstacle_distances(model, data, robot, obst, np.array([True, True]), 1.0)
        ours = np.asarray(fn(jnp.asarray(data.geom_xpos, jnp.float32),
                             jnp.asarray(data.geom_xmat, jnp.float32)))
        for k in range(2):
            if native[k] > 1e-4:
                apart += 1
                assert ours[k] == pytest.approx(native[k], abs=2e-5), (k, native, ours)
            elif native[k] < -1e-4:
                touching += 1
                assert ours[k] <= 0.0, (k, native, ours)
    assert apart > 100 and touching > 20  # both cases seen, on both obstacles


# --------------------------------------------------------------------------- controller
def test_jax_controller_decides_as_the_native_one():
    rng = np.random.default_rng(1)
    c = wr.Controller(turn_deg=60.0, resume_deg=10.0)
    choose = jax.jit(lambda e, m: wm._choose(e, m, c))
    for _ in range(200):
        err, mode = float(rng.uniform(-math.pi, math.pi)), int(rng.integers(3))
        want = wr.choose(err, wr.MODES[mode], c)
        got = choose(jnp.float32(err), jnp.int32(mode))
        assert wr.MODES[int(got[0])] == want.mode
        assert float(got[1]) == pytest.approx(want.steer, abs=1e-5)
        assert float(got[2]) == pytest.approx(want.step, abs=1e-5)
    c = wr.Controller(goal_turn_deg=90.0)
    near_choose = jax.jit(lambda e, m, n: wm._choose_near(e, m, n, c))
    for _ in range(200):
        err, mode = float(rng.uniform(-math.pi, math.pi)), int(rng.integers(3))
        near = bool(rng.integers(2))
        want = wr.choose(err, wr.MODES[mode], wr.near_goal(c) if near else c)
        got = near_choose(jnp.float32(err), jnp.int32(mode), jnp.bool_(near))
        assert wr.MODES[int(got[0])] == want.mode
        assert float(got[2]) == pytest.approx(want.step, abs=1e-5)
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.5, 2.5]])
    cb = wr.Controller(bend_distance=1.2)
    cap = jax.jit(lambda s, p: wm._bend_cap(jnp.asarray(route, jnp.float32), s, p, cb))
    caps = []
    for _ in range(200):
        seg, pos = int(rng.integers(3)), rng.uniform(-0.5, 2.8, 2)
        caps.append(wr.bend_cap(route, seg, pos, cb))
        assert float(cap(jnp.int32(seg), jnp.asarray(pos, jnp.float32))) == pytest.approx(
            caps[-1], abs=1e-5)
    assert min(caps) < 0.9 and max(caps) == 1.0  # both sides of the comparison were exercised
    ctrl = wr.Controller()
    track = jax.jit(lambda s, p: wm._track(jnp.asarray(route, jnp.float32), s, p, ctrl))
    for _ in range(200):
        seg, pos = int(rng.integers(3)), rng.uniform(-0.5, 2.8, 2)
        want_seg, want_target = wr.track(route, seg, pos, ctrl)
        got_seg, got_target = track(jnp.int32(seg), jnp.asarray(pos, jnp.float32))
        assert int(got_seg) == want_seg
        np.testing.assert_allclose(np.asarray(got_target), want_target, atol=1e-5)


# --------------------------------------------------------------------------- worlds
def test_worlds_are_the_native_walkers_worlds(nao):
    """World i of n: the native walker's model fields (obstacle friction included), initial
    pose, latency, push and every control step's target noise."""
    scene = Scene(name="g", bounds=(0.0, -1.0, 3.0, 2.0), start=(0.3, 0.0), goal=(2.8, 1.8),
                  obstacles=(Obstacle(BOX, 0.5), Obstacle(PENTAGON, 0.3)))
    model = sw.scene_model(scene, nao, start_heading=0.4)
    n, steps, push = 3, 40, 30
    native, _ = wr.sample_walk_worlds(model, nao, n, steps, push, seed=5)
    batch, _ = wm.world_batch(model, nao, n, push, (0.3, 0.0), 0.4, seed=5, index=[2, 0])
    for row, i in enumerate((2, 0)):
        w = native[i]
        for f, v in batch.fields.items():
            np.testing.assert_allclose(v[row], getattr(w.model, f), rtol=1e-6, err_msg=f)
        q = np.array(w.qpos, copy=True)
        q[:2] = (0.3, 0.0)
        q[3:7] = [math.cos(0.2), 0.0, 0.0, math.sin(0.2)]
        np.testing.assert_allclose(batch.qpos[row], q, atol=1e-6)
        assert batch.latency[row] == w.latency
        assert (batch.push_start[row], batch.push_stop[row]) == (w.push_start, w.push_stop)
        np.testing.assert_allclose(batch.push_force[row], w.push_force, rtol=1e-6)
        for t in (0, 17, steps - 1):
            noise = jax.random.normal(jax.random.fold_in(batch.noise_key, t), (batch.n_draw,
                                                                               nao.nu))
            np.testing.assert_allclose(
                batch.noise_std[row] * np.asarray(noise)[batch.noise_rows[row]],
                w.noise[t], atol=1e-7)


def test_warp_without_a_gpu_is_refused_in_one_line(tmp_path):
    from eaco_jax.errors import ConfigError
    from eaco_jax.gait.mjx_import import warp_usable
    from eaco_jax.runs import get

    if warp_usable():
        pytest.skip("MuJoCo Warp runs here")
    kind = get("walk")
    with pytest.raises(ConfigError, match="use --impl jax"):
        kind.run(kind.make_settings({"scene": "default", "backend": "mjx", "impl": "warp"}))


# --------------------------------------------------------------------------- walks
def _native_walk(nao, ctrl):
    """The native nominal walk around the box: its record, decisions, model and heading."""
    heading = wr.start_heading(TINY, AROUND)
    model = sw.scene_model(TINY, nao, start_heading=heading)
    dec: list = []
    native = wr.walk(TINY, AROUND, nao, wr.load_walk_gaits("nao"), ctrl, max_time=WALK_TIME,
                     model=model, decisions=dec)
    return native, dec, model, heading


@pytest.fixture(scope="module")
def tiny(nao):
    """The tiny scene's model and the nominal walk around the box on both backends."""
    gaits, ctrl = wr.load_walk_gaits("nao"), wr.Controller()
    native, dec, model, heading = _native_walk(nao, ctrl)
    batch = wm.nominal_batch(model, nao, AROUND[0], heading)
    out = wm.walk_batch(TINY, AROUND, nao, gaits, ctrl, batch, max_time=WALK_TIME,
                        model=model)
    return dict(model=model, gaits=gaits, ctrl=ctrl, native=native, decisions=dec, out=out)


@pytest.mark.slow
def test_mjx_walk_follows_the_native_walk_in_the_nominal_world(tiny):
    rec = wm.records(tiny["out"], AROUND)[0]
    nat = tiny["native"]
    a, b = np.asarray(nat["trajectory"]), np.asarray(rec["trajectory"])
    assert a.shape == b.shape and np.array_equal(a[:, 0], b[:, 0])
    assert np.max(np.linalg.norm(a[:, 1:3] - b[:, 1:3], axis=1)) < PATH_TOL
    ours = wm.decisions(tiny["out"])
    assert len(ours) == len(tiny["decisions"]) >= 7
    for n, m in zip(tiny["decisions"], ours, strict=True):
        assert (n[0], n[1], n[3]) == (m[0], m[1], m[3])  # time, segment, mode
        assert m[2] == pytest.approx(n[2], abs=1e-3)  # heading error
        assert (m[4], m[5]) == pytest.approx((n[4], n[5]), abs=1e-3)  # steer, step
    assert any(abs(d[4]) > 0.5 for d in ours)  # the corner is steered
    for key in ("success", "fell", "contact", "walked_time_s", "gait_switches"):
        assert rec[key] == nat[key], key
    assert rec["closest_approach_m"] == pytest.approx(nat["closest_approach_m"], abs=1e-3)


def test_bend_distance_shortens_the_step_before_the_first_corner(nao):
    """The native walk applies bend_cap: before the first corner (segment 0) its forward
    steps are shorter than without it. Decisions: (time, segment, error, mode, steer, step)."""
    off = _native_walk(nao, wr.Controller())[1]
    on = _native_walk(nao, wr.Controller(bend_distance=1.5))[1]
    assert min(d[5] for d in on if d[1] == 0) < min(d[5] for d in off if d[1] == 0) - 0.05


@pytest.mark.slow
def test_mjx_walk_applies_bend_distance_as_the_native_walk(nao):
    ctrl = wr.Controller(bend_distance=1.5)
    _, native, model, heading = _native_walk(nao, ctrl)
    batch = wm.nominal_batch(model, nao, AROUND[0], heading)
    out = wm.walk_batch(TINY, AROUND, nao, wr.load_walk_gaits("nao"), ctrl, batch,
                        max_time=WALK_TIME, model=model)
    ours = wm.decisions(out)
    assert len(ours) == len(native) >= 7
    for n, m in zip(native, ours, strict=True):
        assert (n[0], n[1], n[3]) == (m[0], m[1], m[3])
        assert (m[4], m[5]) == pytest.approx((n[4], n[5]), abs=1e-3)


@pytest.mark.slow
def test_batched_walk_gives_each_world_its_unbatched_result(nao, tiny):
    """Worlds 1 and 0 of two, with the nominal world, in one call of three; world 1 alone
    in a call of one: the same walk, and the nominal row the same as walked alone (world 1
    sits in a different row of each call)."""
    model, gaits, ctrl = tiny["model"], tiny["gaits"], tiny["ctrl"]
    heading = wr.start_heading(TINY, AROUND)
    push = int(WALK_TIME / nao.control_dt)
    both, _ = wm.world_batch(model, nao, 2, push, AROUND[0], heading, index=[1, 0])
    three = wm.walk_batch(TINY, AROUND, nao, gaits, ctrl,
                          wm.with_nominal(both, model, nao, AROUND[0], heading),
                          max_time=WALK_TIME, model=model)
    one, _ = wm.world_batch(model, nao, 2, push, AROUND[0], heading, index=[1])
    alone = wm.walk_batch(TINY, AROUND, nao, gaits, ctrl, one, max_time=WALK_TIME,
                          model=model)
    recs, single = wm.records(three, AROUND), wm.records(alone, AROUND)[0]
    nominal = wm.records(tiny["out"], AROUND)[0]
    for got, want in ((recs[1], single), (recs[0], nominal)):
        np.testing.assert_allclose(np.asarray(got["trajectory"]),
                                   np.asarray(want["trajectory"]), atol=1e-4)
        assert got["closest_approach_m"] == pytest.approx(want["closest_approach_m"],
                                                          abs=1e-4)
    # the worlds differ from the nominal one and from each other
    ends = [np.asarray(r["trajectory"])[-1, 1:3] for r in recs]
    assert min(np.linalg.norm(ends[i] - ends[j]) for i, j in ((0, 1), (0, 2), (1, 2))) > 1e-3


@pytest.mark.slow
def test_walk_into_an_obstacle_is_a_contact(nao):
    """A route through the box: the walk touches it (the nominal world, MJX-JAX on CPU)."""
    gaits, ctrl = wr.load_walk_gaits("nao"), wr.Controller()
    model = sw.scene_model(TINY, nao)
    batch = wm.nominal_batch(model, nao, THROUGH[0], 0.0)
    out = wm.walk_batch(TINY, THROUGH, nao, gaits, ctrl, batch, max_time=WALK_TIME,
                        model=model)
    rec = wm.records(out, THROUGH)[0]
    assert rec["contact"] and rec["contact_obstacle"] == 0 and not rec["success"]
    assert rec["closest_approach_m"] <= 0.0
    x_touch = np.interp(rec["contact_time_s"], *np.asarray(rec["trajectory"])[:, :2].T)
    assert 1.0 < x_touch < 1.5  # the torso is just short of the box's face at x = 1.5


@pytest.mark.slow
def test_eaco_walk_on_mjx_writes_the_native_record(tmp_path):
    """``eaco walk --backend mjx``: the nominal walk and a world in one call, the record with
    the native backend's fields, naming the backend."""
    import json

    from eaco_jax.runs import get

    path = tmp_path / "tiny.json"
    path.write_text(json.dumps({"name": "tiny", "bounds": [0.0, -2.0, 4.0, 2.0],
                                "start": [0.3, 0.0], "goal": [3.3, 0.0],
                                "obstacles": [{"polygon": [list(p) for p in BOX],
                                               "height": 0.5}]}))
    kind = get("walk")
    common = {"scene": str(path), "planner": "optimal", "max_time": 2.0, "worlds": 1}
    mjx = kind.run(kind.make_settings({**common, "backend": "mjx",
                                       "out": str(tmp_path / "mjx")}))
    native = kind.run(kind.make_settings({**common, "out": str(tmp_path / "native")}))
    assert mjx["backend"] == "mjx-jax" and native["backend"] == "native"
    assert set(mjx) == set(native) and set(mjx["worlds"]) == set(native["worlds"])
    assert set(mjx["nominal"]) == set(native["nominal"])
    assert set(mjx["worlds"]["walks"][0]) == set(native["worlds"]["walks"][0])
    a, b = (np.asarray(r["nominal"]["trajectory"]) for r in (native, mjx))
    assert a.shape == b.shape and np.max(np.abs(a[:, 1:3] - b[:, 1:3])) < PATH_TOL
    assert (tmp_path / "mjx" / "walk.json").is_file() and (tmp_path / "mjx" / "walk.png").is_file()
