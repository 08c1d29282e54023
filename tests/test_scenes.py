"""Scenes, the walking-time cost and its exact yardstick (brute force on tiny scenes)."""

import json
import math

import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.path_planning import GOAL, START
from eaco_jax.problems.scenes import (
    Obstacle,
    Ramp,
    Scene,
    build_problem,
    load_gait_speeds,
    load_scene,
    random_scene,
    scene_from_dict,
    segment_times,
)
from eaco_jax.strategies.path_eaco import PathEACO

SQUARE = ((4.0, 4.0), (6.0, 4.0), (6.0, 6.0), (4.0, 6.0))
RAMP = ((1.0, 6.5), (3.0, 6.5), (3.0, 8.5), (1.0, 8.5))


def _tiny(start_heading=None, ramp=True):
    return Scene(name="tiny", bounds=(0.0, 0.0, 10.0, 10.0), start=(0.5, 5.0), goal=(9.5, 6.0),
                 obstacles=(Obstacle(SQUARE, 0.5), Obstacle(((7.0, 5.5), (8.0, 5.5), (7.5, 7.0)),
                                                            0.8)),
                 ramps=(Ramp(RAMP, 5.0, 30.0),) if ramp else (), clearance=0.3,
                 start_heading_deg=start_heading)


def _simple_paths(free: np.ndarray) -> list[list[int]]:
    """Every simple START -> GOAL path of the graph (depth first)."""
    out, stack = [], [[START]]
    while stack:
        p = stack.pop()
        for k in np.flatnonzero(free[p[-1]]):
            if k == GOAL:
                out.append([*p, GOAL])
            elif k not in p:
                stack.append([*p, int(k)])
    return out


@pytest.mark.parametrize("heading", [None, 200.0])
def test_yardstick_equals_brute_force_over_every_simple_route(heading):
    p = build_problem(_tiny(heading), ramp_edge_points=0)
    routes = _simple_paths(np.isfinite(np.asarray(p.dist)))
    assert 1000 < len(routes) < 2_000_000
    costs = np.asarray(p.evaluate(jnp.asarray(np.stack([p.route(r) for r in routes]))))
    assert p.optimum == pytest.approx(float(costs.min()), rel=1e-5)
    best = routes[int(np.argmin(costs))]
    assert float(np.asarray(p.evaluate(jnp.asarray(p.route(list(p.optimal_route)))[None]))[0]) \
        == pytest.approx(float(costs.min()), rel=1e-5), (best, p.optimal_route)


def test_route_time_by_hand():
    """Flat leg, ramp leg (crossed at an angle), the turn between them and the start turn."""
    speeds = load_gait_speeds()
    scene = Scene(name="hand", bounds=(-1.0, -1.0, 10.0, 10.0), start=(0.0, 0.0), goal=(4.0, 3.0),
                  ramps=(Ramp(((3.0, 1.0), (5.0, 1.0), (5.0, 4.0), (3.0, 4.0)), 5.0, 90.0),),
                  clearance=0.0, start_heading_deg=90.0)
    p = build_problem(scene, speeds, ramp_edge_points=0)
    nodes = [tuple(np.round(c, 6)) for c in np.asarray(p.coords, np.float64)]
    corner = nodes.index((3.0, 1.0))
    t = float(p.evaluate(jnp.asarray(p.route([START, corner, GOAL]))[None])[0])
    v0 = speeds.speed(0.0)
    # leg 1: (0,0) -> (3,1) on the flat; leg 2: (3,1) -> (4,3) all on the ramp, rising along y
    leg1 = math.hypot(3, 1) / v0
    d = np.array([1.0, 2.0]) / math.sqrt(5)
    s = math.atan(math.tan(math.radians(5.0)) * d[1])
    leg2 = math.sqrt(5) / math.cos(s) / speeds.speed(math.degrees(s))
    h1, h2 = math.atan2(1, 3), math.atan2(2, 1)
    turns = (abs(math.pi / 2 - h1) + abs(h2 - h1)) / speeds.yaw_rate
    assert t == pytest.approx(leg1 + leg2 + turns, rel=1e-5)
    # the straight segment (0,0) -> (4,3) enters the ramp at x = 3 (a quarter of it on the ramp)
    direct = segment_times(np.array([[0.0, 0.0]]), np.array([[4.0, 3.0]]), scene.ramps, speeds)
    s = math.atan(math.tan(math.radians(5.0)) * 0.6)
    want = 3.75 / v0 + 1.25 / math.cos(s) / speeds.speed(math.degrees(s))
    assert float(direct[0]) == pytest.approx(want, rel=1e-9)


def test_downhill_is_dearer_or_cheaper_as_the_table_says():
    speeds = load_gait_speeds()
    ramp = (Ramp(((0.0, -1.0), (2.0, -1.0), (2.0, 1.0), (0.0, 1.0)), 5.0, 0.0),)
    up, down = segment_times(np.array([[0.0, 0.0], [2.0, 0.0]]),
                             np.array([[2.0, 0.0], [0.0, 0.0]]), ramp, speeds)
    c = math.cos(math.radians(5.0))
    assert up == pytest.approx(2 / c / speeds.speed(5.0))
    assert down == pytest.approx(2 / c / speeds.speed(-5.0))


def test_default_and_random_scenes():
    s = load_scene("default")
    assert len(s.obstacles) == 10 and len(s.ramps) == 1
    p = build_problem(s)
    assert np.isfinite(p.optimum) and p.optimal_route[0] == START
    a, b = random_scene(7), random_scene(7)
    assert a == b and a != random_scene(8) and len(a.obstacles) == 10
    assert load_scene("random:7") == a
    assert scene_from_dict(json.loads(json.dumps(a.to_dict()))) == a


def test_colony_reaches_the_time_optimum_on_a_scene():
    p = build_problem(random_scene(3))
    r = ea.minimize(p, PathEACO(num_ants=16), seed=0, iterations=40)
    assert float(r.best_cost) <= p.optimum * 1.01
    assert float(p.evaluate(jnp.asarray(r.best_solution)[None])[0]) == pytest.approx(
        float(r.best_cost))


def _bad(tmp_path, **change):
    d = _tiny().to_dict()
    d.update(change)
    f = tmp_path / "scene.json"
    f.write_text(json.dumps(d))
    return f


@pytest.mark.parametrize("change, match", [
    ({"goal": [5.0, 5.0]}, "goal .* lies on obstacle 0"),
    ({"start": [4.1, 5.0]}, "start .* lies on obstacle 0"),
    ({"start": [11.0, 5.0]}, "start .* is off the floor"),
    ({"obstacles": [{"polygon": [[0, 0], [2, 2], [2, 0], [0, 2]], "height": 1}]},
     "obstacle 0: polygon is not simple"),
    ({"obstacles": [{"polygon": [[3, 3], [7, 3], [5, 4], [5, 7]], "height": 1}]},
     "obstacle 0: polygon is not convex"),
    ({"obstacles": [{"polygon": [[8, 4], [9.2, 4], [9.2, 5]], "height": 0}]},
     "height must be > 0"),
    ({"obstacles": [{"polygon": [[8.6, 4.5], [8.8, 4.5], [8.8, 7.5], [8.6, 7.5]], "height": 1},
                    {"polygon": [[8.6, 4.5], [10.5, 4.5], [10.5, 4.7], [8.6, 4.7]], "height": 1},
                    {"polygon": [[8.6, 7.3], [10.5, 7.3], [10.5, 7.5], [8.6, 7.5]], "height": 1}]},
     "goal cannot be reached"),
    ({"ramps": [{"polygon": RAMP, "slope_deg": 12, "uphill_deg": 0}]}, "outside the gait table"),
    ({"ramps": [{"polygon": RAMP, "slope_deg": 5}, {"polygon": RAMP, "slope_deg": 5}]},
     "ramps 0 and 1 overlap"),
    ({"bounds": [0, 0, 10]}, "bounds must be"),
    ({"wall": 1}, "unknown key 'wall'"),
    ({"start": "here"}, r"start must be \[x, y\]"),
])
def test_bad_scenes_get_one_line(tmp_path, change, match):
    with pytest.raises(ProblemError, match=match) as err:
        build_problem(load_scene(_bad(tmp_path, **change)))
    assert "\n" not in str(err.value)


def test_malformed_and_missing_files(tmp_path):
    f = tmp_path / "broken.json"
    f.write_text('{"bounds": [0, 0, 10, 10], ')
    with pytest.raises(ProblemError, match="not valid JSON"):
        load_scene(f)
    with pytest.raises(ProblemError, match="is not a file"):
        load_scene(tmp_path / "nope.json")
    f.write_text("[1, 2]")
    with pytest.raises(ProblemError, match="expected a JSON object"):
        load_scene(f)


def test_cli_plans_a_scene_end_to_end(tmp_path):
    from typer.testing import CliRunner

    from eaco_jax.cli import app

    scene = tmp_path / "tiny.json"
    scene.write_text(json.dumps(_tiny().to_dict()))
    res = CliRunner().invoke(app, ["--no-compile-cache", "path", "--scene", str(scene),
                                   "--strategy", "path-ga", "--ants", "8", "--iterations", "5",
                                   "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    rec = json.loads((tmp_path / "out" / "result.json").read_text())
    p = build_problem(_tiny())
    assert rec["cost"] == "time_s" and rec["optimum"] == pytest.approx(p.optimum)
    assert rec["time_s"] >= p.optimum * (1 - 1e-6) and rec["strategy"] == "path-ga"
    assert (tmp_path / "out" / "path.png").exists()
    bad = CliRunner().invoke(app, ["path", "--scene", str(_bad(tmp_path, goal=[5.0, 5.0]))])
    assert bad.exit_code == 2
    assert [ln for ln in bad.output.splitlines() if ln.strip()] == [
        "error: tiny: goal (5, 5) lies on obstacle 0 (grown by the clearance 0.3 m); move it or "
        "the obstacle"]
