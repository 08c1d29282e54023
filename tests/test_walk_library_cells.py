"""The route walker drawing its forward gait from a gait library's cells (issue #32): the
pick by speed, the library file, the start ramp, a native walk that uses several cells, and the
MJX walker deciding as the native one."""

from __future__ import annotations

import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.errors import ConfigError
from eaco_jax.gait import scene_world as sw
from eaco_jax.gait import walk_route as wr
from eaco_jax.gait import walk_route_mjx as wm
from eaco_jax.gait.robot import load_robot
from eaco_jax.problems.scenes import Obstacle, Scene

BOX = ((1.5, -0.6), (2.0, -0.6), (2.0, 0.6), (1.5, 0.6))
TINY = Scene(name="tiny", bounds=(0.0, -2.0, 4.0, 2.0), start=(0.3, 0.0), goal=(3.3, 0.0),
             obstacles=(Obstacle(BOX, 0.5),))
AROUND = np.array([[0.3, 0.0], [1.3, -0.95], [2.2, -0.95], [3.3, 0.0]])
WALK_TIME = 6.0
LIBRARY = Path(wr.__file__).parent.parent / "data" / "walk_gaits" / "nao_library.json"


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


def _gaits(speeds):
    base = wr.load_walk_gaits("nao_library")
    k = len(speeds)
    cells = np.repeat(base.forward[None], k, 0)
    cells[:, 0] = np.linspace(0.02, 0.1, k)  # tell the cells apart by step length
    return wr.WalkGaits(base.forward, base.turn_left, base.turn_right, "", None, cells,
                        np.asarray(speeds, np.float64))


def test_pick_cell_is_the_fastest_at_or_below_the_wanted_speed():
    g = _gaits([0.1, 0.2, 0.3])
    assert [wr.pick_cell(g, s) for s in (1.0, 0.99, 0.7, 2 / 3, 0.66, 0.34, 0.2)] == \
        [2, 1, 1, 1, 0, 0, 0]  # 0.2 wants 0.06 m/s: below every cell, the slowest
    pick = jax.jit(lambda s: wm._pick_cell(jnp.asarray(g.cell_speed, jnp.float32), s))
    for s in np.random.default_rng(0).uniform(0.05, 1.0, 200):
        assert int(pick(jnp.float32(s))) == wr.pick_cell(g, float(s))


def test_a_forward_choice_walks_its_cell_steered_and_turns_are_left_alone():
    g = _gaits([0.1, 0.3])
    ch = wr.with_cell(wr.Choice(wr.FORWARD, 0.2, 1.0), g)
    assert (ch.cell, ch.steer, ch.step) == (1, 0.2, 1.0)  # full step: the fastest cell
    params = wr.gait_params(g, ch)
    np.testing.assert_array_equal(np.delete(params, wr.TURN), np.delete(g.cells[1], wr.TURN))
    assert params[wr.TURN] == 0.2  # steered; the cell's own step length, not scaled
    slow = wr.with_cell(wr.Choice(wr.FORWARD, -0.1, 0.4), g)
    assert slow.cell == 0
    np.testing.assert_array_equal(np.delete(wr.gait_params(g, slow), wr.TURN),
                                  np.delete(g.cells[0], wr.TURN))
    turn = wr.Choice(wr.LEFT)
    assert wr.with_cell(turn, g) == turn
    np.testing.assert_array_equal(wr.gait_params(g, turn), g.turn_left)
    plain = wr.load_walk_gaits("nao_constrained")
    assert wr.with_cell(wr.Choice(wr.FORWARD, 0.3, 0.5), plain).cell == -1


def test_the_shipped_library_holds_its_cells_slowest_first():
    g = wr.load_walk_gaits("nao_library")
    assert g.n_cells >= 3 and np.all(np.diff(g.cell_speed) > 0)
    np.testing.assert_array_equal(g.forward, g.cells[-1])
    data = json.loads(LIBRARY.read_text())
    assert sorted(c["speed_mps"] for c in data["forward_cells"]) == list(g.cell_speed)


def test_bad_forward_cells_are_one_line(tmp_path):
    src = json.loads(LIBRARY.read_text())
    for change, match in (
            (lambda d: d["forward_cells"][0].pop("speed_mps"), "needs vector and speed_mps"),
            (lambda d: d["forward_cells"][0].update(speed_mps=-0.1), "speed_mps > 0"),
            (lambda d: d["forward_cells"][1].update(speed_mps=float("nan")), "speed_mps > 0"),
            (lambda d: d.update(forward_cells=[]), "at least one cell"),
            (lambda d: d["forward_cells"][2]["vector"].pop(), r"forward_cells\[2\].vector")):
        bad = json.loads(json.dumps(src))
        change(bad)
        (tmp_path / "bad.json").write_text(json.dumps(bad))
        with pytest.raises(ConfigError, match=match):
            wr.load_walk_gaits(tmp_path / "bad.json")


def test_the_start_ramp_caps_the_step_from_min_step_to_full():
    c = wr.Controller(start_ramp_s=4.0, min_step=0.35)
    caps = [wr.start_cap(t, c) for t in (0.0, 1.0, 2.0, 3.9, 4.0, 9.0)]
    assert caps == pytest.approx([0.35, 0.35, 0.5, 0.975, 1.0, 1.0])
    assert wr.start_cap(0.0, wr.Controller()) == 1.0  # 0: off
    cap = jax.jit(lambda t: wm._start_cap(t, c))
    for t in np.linspace(0.0, 6.0, 61):
        assert float(cap(jnp.float32(t))) == pytest.approx(wr.start_cap(float(t), c), abs=1e-6)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match="start_ramp_s must be a finite number >= 0"):
            wr.Controller(start_ramp_s=bad)


def test_a_library_names_its_start_ramp_and_a_walk_takes_it_unless_told(tmp_path):
    from eaco_jax.runs.walk import WalkSettings

    g = wr.load_walk_gaits("nao_library")
    assert g.start_ramp_s > 0
    assert WalkSettings(gaits="nao_library").controller(g).start_ramp_s == g.start_ramp_s
    assert WalkSettings(gaits="nao_library", start_ramp_s=0.0).controller(g).start_ramp_s == 0
    assert WalkSettings().controller(wr.load_walk_gaits("nao_constrained")).start_ramp_s == 0
    src = json.loads(LIBRARY.read_text())
    for ctrl, msg in (({"lookahead": 2.0}, "controller may only set start_ramp_s, turn_deg"),
                      ({"start_ramp_s": "3"}, "controller may only set"),
                      ({"turn_deg": True}, "controller may only set"),
                      ([3.0], "controller may only set"),
                      ({"start_ramp_s": -2.0}, "bad.json: controller start_ramp_s must be"),
                      ({"turn_deg": 10.0}, "bad.json: controller resume_deg must be in")):
        (tmp_path / "bad.json").write_text(json.dumps({**src, "controller": ctrl}))
        with pytest.raises(ConfigError, match=msg):
            wr.load_walk_gaits(tmp_path / "bad.json")


def test_a_library_may_choose_controller_settings_and_a_walk_overrides_them(tmp_path):
    from eaco_jax.runs.walk import WalkSettings

    src = json.loads(LIBRARY.read_text())
    chosen = {"start_ramp_s": 2.0, "turn_deg": 50.0, "max_steer": 0.5, "claim": "x"}
    (tmp_path / "lib.json").write_text(json.dumps({**src, "controller": chosen}))
    g = wr.load_walk_gaits(tmp_path / "lib.json")
    c = WalkSettings(gaits=str(tmp_path / "lib.json")).controller(g)
    assert (c.start_ramp_s, c.turn_deg, c.max_steer) == (2.0, 50.0, 0.5)
    assert c.min_step == wr.Controller.min_step and c.steer_gain == wr.Controller.steer_gain
    c = WalkSettings(turn_deg=180.0, min_step=0.5).controller(g)  # the walk's own win
    assert (c.turn_deg, c.max_steer, c.min_step) == (180.0, 0.5, 0.5)
    assert WalkSettings().controller() == wr.Controller()  # no library: the defaults


def _native(nao, gaits, ctrl=None):
    heading = wr.start_heading(TINY, AROUND)
    model = sw.scene_model(TINY, nao, start_heading=heading)
    dec: list = []
    rec = wr.walk(TINY, AROUND, nao, gaits, ctrl or wr.Controller(), max_time=WALK_TIME,
                  model=model, decisions=dec, motors="spec")
    return rec, dec, model, heading


def test_a_native_walk_draws_on_several_cells(nao):
    g = wr.load_walk_gaits("nao_library")
    rec, dec, _, _ = _native(nao, g)
    used = [i for i, t in enumerate(rec["cell_seconds"]) if t > 0]
    assert len(used) >= 2 and g.n_cells - 1 in used  # the fastest, and a slower one at a bend
    assert sum(rec["cell_seconds"]) == pytest.approx(rec["mode_seconds"][wr.FORWARD], abs=1e-6)
    assert not rec["fell"]
    plain = wr.walk(TINY, AROUND, nao, wr.load_walk_gaits("nao_constrained"), wr.Controller(),
                    max_time=1.0, motors="spec")
    assert plain["cell_seconds"] is None


def test_a_walk_with_a_start_ramp_starts_on_the_slowest_cell(nao):
    g = wr.load_walk_gaits("nao_library")
    ctrl = wr.Controller(start_ramp_s=4.0)
    rec, dec, _, _ = _native(nao, g, ctrl)
    assert dec[0][5] == pytest.approx(ctrl.min_step) and wr.pick_cell(g, dec[0][5]) == 0
    for t, _, _, mode, _, step in dec:
        if mode == wr.FORWARD:
            assert step <= wr.start_cap(t, ctrl) + 1e-9
    assert rec["cell_seconds"][0] > 0.5  # it walked the slowest cell first


@pytest.mark.slow
def test_mjx_walk_draws_on_the_cells_as_the_native_walk(nao):
    g = wr.load_walk_gaits("nao_library")
    ctrl = wr.Controller(start_ramp_s=3.0)  # the ramp too
    native, dec, model, heading = _native(nao, g, ctrl)
    batch = wm.nominal_batch(model, nao, AROUND[0], heading)
    out = wm.walk_batch(TINY, AROUND, nao, g, ctrl, batch, max_time=WALK_TIME,
                        model=model, motors="spec")
    rec = wm.records(out, AROUND)[0]
    ours = wm.decisions(out)
    assert len(ours) == len(dec) >= 7
    for n, m in zip(dec, ours, strict=True):
        assert (n[0], n[1], n[3]) == (m[0], m[1], m[3])
        assert (m[4], m[5]) == pytest.approx((n[4], n[5]), abs=1e-3)
    assert rec["cell_seconds"] == pytest.approx(native["cell_seconds"], abs=0.05)
    a, b = np.asarray(native["trajectory"]), np.asarray(rec["trajectory"])
    assert np.max(np.linalg.norm(a[:, 1:3] - b[:, 1:3], axis=1)) < 1e-2
