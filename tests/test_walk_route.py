"""Walking a planned route: the scene's geoms in the MuJoCo model, the path-following
controller's choices, and a short real walk on native MuJoCo (issue #32, item 4)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from eaco_jax.errors import ConfigError
from eaco_jax.gait import scene_world as sw
from eaco_jax.gait import walk_route as wr
from eaco_jax.gait.robot import load_robot
from eaco_jax.problems.scenes import Obstacle, Ramp, Scene


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def _scene(**kw) -> Scene:
    base = dict(name="t", bounds=(0.0, 0.0, 4.0, 3.0), start=(0.5, 0.5), goal=(3.5, 2.5))
    base.update(kw)
    return Scene(**base)


SQUARE = ((1.0, 1.0), (2.0, 1.0), (2.0, 1.5), (1.0, 1.5))  # a rectangle: a box geom
PENTAGON = ((3.0, 0.2), (3.6, 0.4), (3.7, 1.0), (3.2, 1.3), (2.8, 0.8))  # a mesh geom
RAMP = Ramp(((0.5, 2.0), (2.5, 2.0), (2.5, 2.8), (0.5, 2.8)), slope_deg=5.0, uphill_deg=0.0)


def _surface_height(model, data, x: float, y: float) -> float:
    """Height of the first surface a ray cast straight down at (x, y) hits (static geoms)."""
    geomid = np.zeros(1, np.int32)
    dist = mujoco.mj_ray(model, data, np.array([x, y, 3.0]), np.array([0.0, 0.0, -1.0]),
                         None, 1, -1, geomid)
    return 3.0 - dist, int(geomid[0])


def test_scene_geoms_stand_where_the_scene_says(nao):
    scene = _scene(obstacles=(Obstacle(SQUARE, 0.4), Obstacle(PENTAGON, 0.7)), ramps=(RAMP,))
    model = sw.scene_model(scene, nao, start_heading=0.3)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    obst, ramps = sw.geom_ids(model, "obstacle"), sw.geom_ids(model, "ramp")
    assert len(obst) == 2 and len(ramps) == 1
    assert model.geom_type[obst[0]] == mujoco.mjtGeom.mjGEOM_BOX
    assert model.geom_type[obst[1]] == mujoco.mjtGeom.mjGEOM_MESH
    # a ray down inside each footprint lands on its top; just outside, on the floor
    for gid, poly, h in ((obst[0], SQUARE, 0.4), (obst[1], PENTAGON, 0.7)):
        c = np.mean(poly, axis=0)
        z, hit = _surface_height(model, data, *c)
        assert hit == gid and z == pytest.approx(h, abs=1e-6)
        for v in np.asarray(poly):  # corners pulled 1 cm in: on top; pushed 1 cm out: floor
            inward = 0.01 * (c - v) / np.linalg.norm(c - v)
            z_in, hit_in = _surface_height(model, data, *(v + inward))
            assert hit_in == gid and z_in == pytest.approx(h, abs=1e-6)
            z_out, hit_out = _surface_height(model, data, *(v - inward))
            assert hit_out not in (gid,) and z_out == pytest.approx(0.0, abs=1e-6)
    # the ramp rises 5 deg towards +x from its low edge at x = 0.5
    for x in (0.6, 1.5, 2.4):
        z, hit = _surface_height(model, data, x, 2.4)
        assert hit == ramps[0]
        assert z == pytest.approx(math.tan(math.radians(5.0)) * (x - 0.5), abs=1e-6)
    # the robot stands at the start, facing the start heading
    assert data.qpos[:2] == pytest.approx([0.5, 0.5])
    assert wr._yaw(data.qpos[3:7]) == pytest.approx(0.3, abs=1e-6)
    # obstacles touch the soles as the floor does; the robot's other geoms touch nothing
    floor = model.geom("floor").id
    for g in obst + ramps:
        assert (model.geom_contype[g], model.geom_conaffinity[g]) == (
            model.geom_contype[floor], model.geom_conaffinity[floor])


def test_ramp_heights_fall_the_other_way_for_a_negative_slope():
    poly = np.array(RAMP.polygon)
    up = sw.ramp_heights(poly, 5.0, 0.0)
    down = sw.ramp_heights(poly, -5.0, 0.0)
    assert up.min() == 0.0 and down.min() == 0.0
    assert np.allclose(up + down, up.max())  # mirror images: high where the other is low
    assert up[1] == pytest.approx(2.0 * math.tan(math.radians(5.0)))


def test_rectangle_is_recognised_and_a_rhombus_is_not():
    centre, half, yaw = sw.rectangle(np.array(SQUARE))
    assert centre == pytest.approx([1.5, 1.25]) and half == pytest.approx([0.5, 0.25])
    assert yaw == pytest.approx(0.0)
    assert sw.rectangle(np.array([(0, 0), (2, 0), (3, 1), (1, 1)], float)) is None


def test_obstacle_distance_finds_a_contact(nao):
    box = ((0.55, -0.3), (0.9, -0.3), (0.9, 0.3), (0.55, 0.3))
    scene = _scene(start=(0.0, 0.0), obstacles=(Obstacle(box, 0.5),))
    model = sw.scene_model(scene, nao)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    robot, obst = sw.robot_geom_ids(model), sw.geom_ids(model, "obstacle")
    far = sw.obstacle_distances(model, data, robot, obst, np.array([True]), 1.0)[0]
    assert 0.2 < far < 0.55
    data.qpos[0] = far + 0.02  # moved 2 cm past the gap: overlap
    mujoco.mj_forward(model, data)
    near = sw.obstacle_distances(model, data, robot, obst, np.array([True]), 1.0)[0]
    assert near == pytest.approx(-0.02, abs=2e-3)


# --------------------------------------------------------------------------- controller
def test_choose_turns_on_the_spot_for_a_large_error_and_steers_a_small_one():
    c = wr.Controller(turn_deg=20.0, resume_deg=8.0, steer_gain=1.0)
    assert wr.choose(math.radians(40), wr.FORWARD, c) == wr.Choice(wr.LEFT)
    assert wr.choose(math.radians(-40), wr.FORWARD, c) == wr.Choice(wr.RIGHT)
    ch = wr.choose(math.radians(10), wr.FORWARD, c)
    assert ch.mode == wr.FORWARD and ch.steer == pytest.approx(math.radians(10))
    ch = wr.choose(math.radians(-10), wr.FORWARD, c)
    assert ch.mode == wr.FORWARD and ch.steer == pytest.approx(-math.radians(10))
    # hysteresis: a turn goes on until the error is below resume_deg
    assert wr.choose(math.radians(10), wr.LEFT, c).mode == wr.LEFT
    assert wr.choose(math.radians(5), wr.LEFT, c).mode == wr.FORWARD
    # an overshoot hands a turn to the forward gait (steering back), not to the opposite turn
    ch = wr.choose(math.radians(-30), wr.LEFT, c)
    assert ch.mode == wr.FORWARD and ch.steer < 0
    assert wr.choose(math.radians(30), wr.RIGHT, c).mode == wr.FORWARD
    # the steering is clipped to max_steer
    assert wr.choose(math.radians(12), wr.FORWARD,
                     wr.Controller(steer_gain=5.0, max_steer=0.7)).steer == pytest.approx(0.7)


def test_default_controller_takes_corners_on_arcs_that_tighten_with_the_error():
    c = wr.Controller(slow_deg=15.0, stop_deg=45.0, min_step=0.4)
    assert wr.Controller().turn_deg == 180.0  # never on the spot by default
    for deg in (-170.0, -90.0, 90.0, 170.0):
        assert wr.choose(math.radians(deg), wr.FORWARD, wr.Controller()).mode == wr.FORWARD
    assert wr.choose(math.radians(10), wr.FORWARD, c).step == 1.0  # below slow_deg: full step
    assert wr.choose(math.radians(-30), wr.FORWARD, c).step == pytest.approx(0.7)  # halfway
    assert wr.choose(math.radians(80), wr.FORWARD, c).step == pytest.approx(0.4)  # floor
    g = wr.load_walk_gaits("nao")
    p = wr.gait_params(g, wr.Choice(wr.FORWARD, -0.5, 0.4))
    assert p[wr.STEP] == pytest.approx(0.4 * g.forward[wr.STEP]) and p[wr.TURN] == -0.5
    others = [i for i in range(len(p)) if i not in (wr.STEP, wr.TURN)]
    assert np.array_equal(p[others], g.forward[others])
    assert np.array_equal(wr.gait_params(g, wr.Choice(wr.LEFT, 0.3, 0.5)), g.turn_left)


def test_the_steered_forward_gait_turns_the_way_it_is_steered(nao):
    """The physics behind the arcs: the stored forward gait with turn_rate +-0.6 rad/s and
    its step at 0.5 turns the NAO by tens of degrees in 4 s, left for +, right for -."""
    g = wr.load_walk_gaits("nao")
    scene = _scene(start=(0.0, 0.0), goal=(3.0, 0.0), bounds=(-3.0, -3.0, 3.0, 3.0))
    model = sw.scene_model(scene, nao)
    turned = []
    for steer in (0.6, -0.6):
        params = wr.gait_params(g, wr.Choice(wr.FORWARD, steer, 0.5))
        data = mujoco.MjData(model)
        data.qpos[:] = sw.start_qpos(nao, model, (0.0, 0.0), 0.0)
        data.ctrl[:] = nao.stand_ctrl
        mujoco.mj_forward(model, data)
        sub = int(round(nao.control_dt / model.opt.timestep))
        n = int(4.0 / nao.control_dt)
        times = np.arange(n) * nao.control_dt
        targets = np.asarray(wr._targets_fn(nao)(
            np.repeat(params[None], n, 0).astype(np.float32), times.astype(np.float32)))
        for u in targets:
            data.ctrl[:] = wr.couple_controls(u[None], nao, xp=np)[0]
            for _ in range(sub):
                mujoco.mj_step(model, data)
        assert data.qpos[2] > nao.fall_height
        turned.append(math.degrees(wr._yaw(data.qpos[3:7])))
    assert turned[0] > 40.0 and turned[1] < -40.0


def test_track_stays_on_the_segment_and_moves_on_at_its_end():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    c = wr.Controller(lookahead=0.5, capture=0.1)
    seg, target = wr.track(route, 0, np.array([0.5, 0.2]), c)
    assert seg == 0 and target == pytest.approx([1.0, 0.0])
    seg, target = wr.track(route, 0, np.array([1.8, 0.1]), c)  # no corner cutting
    assert seg == 0 and target == pytest.approx([2.0, 0.0])
    seg, target = wr.track(route, 0, np.array([1.95, 0.0]), c)
    assert seg == 1 and target == pytest.approx([2.0, 0.5])
    # the last segment is never left
    seg, _ = wr.track(route, 1, np.array([2.0, 2.5]), c)
    assert seg == 1


def test_bad_controller_settings_are_one_line():
    with pytest.raises(ConfigError, match="resume_deg"):
        wr.Controller(turn_deg=10.0, resume_deg=12.0)
    with pytest.raises(ConfigError, match="turn_deg"):
        wr.Controller(turn_deg=200.0)
    with pytest.raises(ConfigError, match="slow_deg"):
        wr.Controller(slow_deg=50.0, stop_deg=40.0)
    with pytest.raises(ConfigError, match="min_step"):
        wr.Controller(min_step=0.0)
    with pytest.raises(ConfigError, match="lookahead"):
        wr.Controller(lookahead=-1.0)


def test_ground_height_and_polygon_distance():
    planes = wr._ramp_planes(SimpleNamespace(ramps=(RAMP,)))
    assert wr.ground_height(planes, np.array([1.5, 2.4])) == pytest.approx(
        math.tan(math.radians(5.0)))
    assert wr.ground_height(planes, np.array([1.5, 1.0])) == 0.0
    sq = np.array(SQUARE)
    assert wr.polygon_distance(np.array([1.5, 1.2]), sq) == 0.0
    assert wr.polygon_distance(np.array([2.3, 1.2]), sq) == pytest.approx(0.3)
    assert wr.polygon_distance(np.array([2.3, 1.9]), sq) == pytest.approx(0.5)


def test_library_turning_gaits_step_in_place(nao):
    g = wr.load_walk_gaits("nao")
    assert g.turn_left[0] == 0.0 and g.turn_right[0] == 0.0
    assert g.turn_left[wr.TURN] > 0 > g.turn_right[wr.TURN]
    assert g.forward[0] > 0.05


def test_near_the_goal_the_controller_turns_on_the_spot_above_goal_turn_deg():
    c = wr.Controller(goal_turn_deg=90.0)
    assert wr.near_goal(wr.Controller(goal_turn_deg=180.0)).turn_deg == 180.0  # 180: never
    assert wr.choose(math.radians(100), wr.FORWARD, wr.near_goal(c)).mode == wr.LEFT
    assert wr.choose(math.radians(-100), wr.FORWARD, wr.near_goal(c)).mode == wr.RIGHT
    assert wr.choose(math.radians(80), wr.FORWARD, wr.near_goal(c)).mode == wr.FORWARD
    assert wr.choose(math.radians(100), wr.FORWARD, c).mode == wr.FORWARD  # away from it
    assert wr.near_goal(wr.Controller(turn_deg=60.0, goal_turn_deg=90.0)).turn_deg == 60.0
    with pytest.raises(ConfigError, match="goal_turn_deg must be in"):
        wr.Controller(goal_turn_deg=10.0)  # not above resume_deg
    with pytest.raises(ConfigError, match="goal_turn_deg"):
        wr.Controller(goal_turn_deg=math.nan)


def test_a_gait_library_with_a_bad_vector_is_one_line_naming_the_entry(tmp_path):
    src = json.loads((Path(wr.__file__).parent.parent / "data" / "walk_gaits" / "nao.json")
                     .read_text())
    bad = json.loads(json.dumps(src))
    bad["gaits"]["turn_left"]["vector"][3] = float("nan")
    (tmp_path / "nan.json").write_text(json.dumps(bad))
    with pytest.raises(ConfigError, match=r"gaits.turn_left.vector needs \d+ finite parameters, "
                                          r"got NaN or infinite at index 3 \("):
        wr.load_walk_gaits(tmp_path / "nan.json")
    bad = json.loads(json.dumps(src))
    bad["gaits"]["forward"]["vector"] = bad["gaits"]["forward"]["vector"][:-1]
    (tmp_path / "short.json").write_text(json.dumps(bad))
    with pytest.raises(ConfigError, match=r"gaits.forward.vector needs \d+ finite parameters, "
                                          r"got shape"):
        wr.load_walk_gaits(tmp_path / "short.json")


def test_bend_cap_slows_the_step_before_a_bend_by_its_turn():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.5, 2.5]])
    c = wr.Controller(bend_distance=1.0, slow_deg=0.0, stop_deg=90.0, min_step=0.4)
    at_bend = wr.bend_cap(route, 0, np.array([2.0, 0.0]), c)  # a 90 deg left turn, reached
    assert at_bend == pytest.approx(0.4) == pytest.approx(wr.step_fraction(math.pi / 2, c))
    half = wr.bend_cap(route, 0, np.array([1.5, 0.0]), c)  # half the distance: 45 deg
    assert half == pytest.approx(wr.step_fraction(math.pi / 4, c)) == pytest.approx(0.7)
    assert wr.bend_cap(route, 0, np.array([0.5, 0.0]), c) == 1.0  # farther than bend_distance
    assert wr.bend_cap(route, 2, np.array([1.0, 2.3]), c) == 1.0  # the last segment: no bend
    assert wr.bend_cap(route, 0, np.array([2.0, 0.0]), wr.Controller()) == 1.0  # 0: off
    assert wr.Controller().bend_distance == 0.0  # off until measured
    with pytest.raises(ConfigError, match="bend_distance must be a finite number >= 0"):
        wr.Controller(bend_distance=-0.5)


def test_walk_settings_default_to_the_controller_defaults():
    import dataclasses

    from eaco_jax.runs.walk import WalkSettings

    assert WalkSettings().controller() == wr.Controller()
    assert {f.name for f in dataclasses.fields(wr.Controller)} - {"goal_radius"} <= {
        f.name for f in dataclasses.fields(WalkSettings)}


def test_planning_prices_the_gait_librarys_walking_model():
    from eaco_jax.problems.scenes import load_gait_speeds
    from eaco_jax.runs.walk import planning_speeds

    plan = wr.load_walk_gaits("nao").planning
    walk, path = planning_speeds("walk", "nao"), planning_speeds("nao", "nao")
    assert path == load_gait_speeds("nao")
    assert float(walk.speed(0.0)) == pytest.approx(plan["speed_mps"])
    assert walk.yaw_rate_deg_s == plan["yaw_rate_deg_s"]
    ratio = plan["speed_mps"] / float(path.speed(0.0))  # slope rows keep their proportion
    assert np.allclose(walk.speeds_mps, np.asarray(path.speeds_mps) * ratio)
    assert walk.slopes_deg == path.slopes_deg


def test_gait_library_planning_entry_is_checked(tmp_path):
    import json

    data = json.loads((Path(wr.__file__).parents[1] / "data" / "walk_gaits" / "nao.json")
                      .read_text())
    data["planning"] = {"speed_mps": 0.5, "yaw_rate_deg_s": -3.0}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="planning needs"):
        wr.load_walk_gaits(bad)


# --------------------------------------------------------------------------- end to end
SMALL = {"name": "small", "bounds": [0.0, -1.5, 5.0, 1.5], "start": [0.3, 0.0],
         "goal": [4.3, 0.0], "clearance": 0.15,
         "obstacles": [{"polygon": [[1.8, -0.3], [2.4, -0.3], [2.4, 0.25], [1.8, 0.25]],
                        "height": 0.5}]}


def _small_run(tmp_path, **kw):
    import json

    from eaco_jax.runs import get

    path = tmp_path / "small.json"
    path.write_text(json.dumps(SMALL))
    kind = get("walk")
    return kind.run(kind.make_settings({"scene": str(path), "out": str(tmp_path / "out"), **kw}))


def test_small_scene_planned_then_walked_makes_progress(tmp_path):
    rec = _small_run(tmp_path, planner="path-eaco", plan_iterations=10, max_time=8.0)
    route = np.asarray(rec["route"])
    assert len(route) >= 3  # the obstacle on the straight line bends the route
    nom = rec["nominal"]
    assert not nom["fell"] and not nom["contact"]
    start_gap = float(np.linalg.norm(route[-1] - route[0]))
    assert nom["goal_distance_m"] < start_gap - 1.2  # 1.2 m closer in 8 s, two turns included
    assert nom["closest_approach_m"] > 0.0
    walked = np.asarray(nom["trajectory"])[:, 1:3]
    assert max(_route_distance(p, route) for p in walked) < 0.3  # it follows the route
    assert (tmp_path / "out" / "walk.json").is_file() and (tmp_path / "out" / "walk.png").is_file()


def _route_distance(p: np.ndarray, route: np.ndarray) -> float:
    out = np.inf
    for a, b in zip(route[:-1], route[1:], strict=True):
        t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        out = min(out, float(np.linalg.norm(a + t * (b - a) - p)))
    return out


@pytest.mark.slow
def test_small_scene_walked_to_the_goal_in_randomised_worlds(tmp_path):
    rec = _small_run(tmp_path, planner="optimal", worlds=4)
    assert rec["nominal"]["success"]
    assert rec["nominal"]["reach_time_s"] < 1.6 * rec["planning"]["planned_time_s"]
    w = rec["worlds"]
    assert w["n"] == 4 and w["successes"] == sum(x["success"] for x in w["walks"])
    lo, hi = w["success_rate_ci95"]
    assert lo <= w["success_rate"] <= hi


def test_the_constrained_library_walks_the_stored_flat_gait():
    """``nao_constrained``: forward is the stored flat gait (flat_r32) as stored; the turning
    gaits are it stepping in place at the walk engine's turn bound; the planning entry is the
    time model fitted on the tuning walks."""
    from eaco_jax.gait.walk_engine import PARAM_NAMES

    root = Path(wr.__file__).parents[2]
    g = wr.load_walk_gaits("nao_constrained")
    flat = json.loads((root / "experiments/results/nao_constrained_warp/flat_r32/"
                       "best_gait.json").read_text())
    np.testing.assert_array_equal(g.forward, np.asarray(flat["vector"], np.float64))
    i, j = PARAM_NAMES.index("step_length"), PARAM_NAMES.index("turn_rate")
    for vec, rate in ((g.turn_left, 0.3), (g.turn_right, -0.3)):
        assert vec[i] == 0.0 and vec[j] == rate
        keep = [k for k in range(len(PARAM_NAMES)) if k not in (i, j)]
        np.testing.assert_array_equal(vec[keep], g.forward[keep])
    fit = json.loads((root / "experiments/results/walk/tuning_constrained.json").read_text())
    fit = fit["configs"][0]["time_model"]
    assert g.planning["speed_mps"] == pytest.approx(fit["speed_mps"], abs=5e-4)
    assert g.planning["yaw_rate_deg_s"] == pytest.approx(fit["yaw_rate_deg_s"], abs=0.05)
