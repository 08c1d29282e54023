"""Route walks on the robot spec's motor model (``motors="spec"``): the setting, the next
control step's target known before its decision, currents within the limit (the servos'
exceed it), the record naming the setting, and MJX-JAX following the native walker."""

from __future__ import annotations

import json

import numpy as np
import pytest

from eaco_jax.errors import ConfigError
from eaco_jax.gait import scene_world as sw
from eaco_jax.gait import walk_route as wr
from eaco_jax.gait.robot import load_robot
from eaco_jax.problems.scenes import Obstacle, Scene

BOX = ((1.5, -0.6), (2.0, -0.6), (2.0, 0.6), (1.5, 0.6))
TINY = Scene(name="tiny", bounds=(0.0, -2.0, 4.0, 2.0), start=(0.3, 0.0), goal=(3.3, 0.0),
             obstacles=(Obstacle(BOX, 0.5),))
AROUND = np.array([[0.3, 0.0], [1.3, -0.95], [2.2, -0.95], [3.3, 0.0]])  # around the box
SHORT = 1.5  # s: the start-up ramp and the first steered cycles
WALK_TIME = 3.0  # s (slow test): three decisions steer the first corner

#: torso path MJX-JAX (float32) vs native (float64), both under motors="spec", the tiny
#: scene, WALK_TIME: measured 1.3e-5 m in the nominal world, 3.1e-5 m in world 1 of 2 (its push
#: at 2.5 s); 1 mm, a hundredth of a step, fails for one control step's shift of any decision
PATH_TOL = 1e-3
#: a randomised world may drift further: in world 1 of another draw (a 2 s walk, its push at
#: 1.5 s) the paths agree within 2e-6 m until the push and part by 1.2e-3 m 0.4 s after it
#: (float32 physics through the current limit's clip; the native walk moves 6e-7 m for a
#: 1e-6 rad change of the initial joints); 5 mm, a twentieth of a step
WORLD_PATH_TOL = 5e-3


@pytest.fixture(scope="module")
def nao():
    return load_robot("nao")


@pytest.fixture(scope="module")
def short(nao):
    """Short native walks of the tiny scene: the nominal world under both settings, world 1
    of 2 under "spec"."""
    gaits, ctrl = wr.load_walk_gaits("nao"), wr.Controller()
    model = sw.scene_model(TINY, nao, start_heading=wr.start_heading(TINY, AROUND))
    steps = int(np.ceil(SHORT / nao.control_dt))
    worlds, _ = wr.sample_walk_worlds(model, nao, 2, steps, steps)
    run = lambda motors, world=None: wr.walk(  # noqa: E731
        TINY, AROUND, nao, gaits, ctrl, max_time=SHORT, model=model, world=world,
        motors=motors)
    return {"servo": run("servo"), "spec": run("spec"), "world": run("spec", worlds[1]),
            "world_servo": run("servo", worlds[1])}


def test_the_setting_is_the_specs_motor_model(nao):
    assert wr.motor_physics(nao, "servo") == (False, False)
    assert wr.motor_physics(nao, "spec") == (True, True)  # nao.json: limits, interpolation
    with pytest.raises(ConfigError, match="motors must be one of servo, spec"):
        wr.motor_physics(nao, "dc")
    from eaco_jax.runs import get

    with pytest.raises(ConfigError):
        get("walk").make_settings({"motors": "dc"})


def test_the_next_cycles_first_target_does_not_wait_for_its_decision(nao):
    """Interpolating toward the next control step's target needs it before the decision
    that starts the next step cycle: that step runs the blend where it stands, so the
    chunk's extra row is the next chunk's first whatever the decision."""
    gaits = wr.load_walk_gaits("nao")
    fn = wr._targets_fn(nao)
    dt = nao.control_dt
    a = wr.gait_params(gaits, wr.Choice(wr.FORWARD, 0.0, 1.0))
    b = wr.gait_params(gaits, wr.Choice(wr.FORWARD, 0.6, 0.5))
    k0 = 80  # past the start-up ramp
    chunk, phase, alpha = wr._cycle(a, b, 0.0, 3.75, k0, dt, 0.5, fn, extra=True)
    held, phase2, alpha2 = wr._cycle(a, b, 0.0, 3.75, k0, dt, 0.5, fn)
    np.testing.assert_array_equal(chunk[:-1], held)
    assert (phase, alpha) == (phase2, alpha2) and 0.0 < alpha < 1.0
    k1 = k0 + len(held)
    blended = (1 - alpha) * a + alpha * b
    for choice in (wr.Choice(wr.FORWARD, -0.8, 0.35), wr.Choice(wr.LEFT)):
        nxt, _, _ = wr._cycle(blended, wr.gait_params(gaits, choice), 0.0, phase, k1, dt,
                              0.5, fn)
        np.testing.assert_allclose(chunk[-1], nxt[0], atol=1e-6)
        assert np.max(np.abs(nxt[1] - nxt[0])) > 1e-4  # the targets do move per step


def test_spec_currents_stay_within_the_limit_where_the_servos_exceed_it(short):
    """Under "spec" the largest motor current is the limit (the walk reaches it), under
    the servos it is well above (the gait rollouts' currents, the same functions)."""
    for key in ("spec", "world"):
        assert short[key]["motors"] == "spec"
        assert 0.9 < short[key]["peak_current_frac"] <= 1.0 + 1e-9, key
    for key in ("servo", "world_servo"):
        assert short[key]["motors"] == "servo"
        assert short[key]["peak_current_frac"] > 1.2, key  # measured 1.37 and 1.35
    for a, b in (("spec", "servo"), ("world", "world_servo")):
        pa, pb = (np.asarray(short[x]["trajectory"])[:, 1:4] for x in (a, b))
        assert pa.shape == pb.shape and np.max(np.abs(pa - pb)) > 1e-3, (a, b)
    assert not any(short[k]["fell"] for k in short)


def test_eaco_walk_names_the_motor_model(tmp_path):
    """``eaco walk --motors spec``: the record and every walk in it name the setting."""
    from eaco_jax.runs import get

    path = tmp_path / "tiny.json"
    path.write_text(json.dumps({"name": "tiny", "bounds": [0.0, -2.0, 4.0, 2.0],
                                "start": [0.3, 0.0], "goal": [3.3, 0.0],
                                "obstacles": [{"polygon": [list(p) for p in BOX],
                                               "height": 0.5}]}))
    kind = get("walk")
    rec = kind.run(kind.make_settings({"scene": str(path), "planner": "optimal",
                                       "max_time": 0.6, "worlds": 1, "motors": "spec"}))
    assert rec["motors"] == "spec" and rec["settings"]["motors"] == "spec"
    assert rec["nominal"]["motors"] == "spec" and rec["worlds"]["walks"][0]["motors"] == "spec"
    assert rec["nominal"]["peak_current_frac"] <= 1.0 + 1e-9


@pytest.mark.slow
def test_mjx_follows_the_native_walk_on_the_specs_motor_model(nao):
    """The nominal world and world 1 of 2 in one MJX-JAX call against the native walks,
    both under "spec": the same decisions, paths within the tolerance, currents at the
    limit."""
    from eaco_jax.gait import walk_route_mjx as wm

    gaits, ctrl = wr.load_walk_gaits("nao"), wr.Controller()
    heading = wr.start_heading(TINY, AROUND)
    model = sw.scene_model(TINY, nao, start_heading=heading)
    steps = int(np.ceil(WALK_TIME / nao.control_dt))
    worlds, _ = wr.sample_walk_worlds(model, nao, 2, steps, steps)
    one, _ = wm.world_batch(model, nao, 2, steps, AROUND[0], heading, index=[1])
    out = wm.walk_batch(TINY, AROUND, nao, gaits, ctrl,
                        wm.with_nominal(one, model, nao, AROUND[0], heading),
                        max_time=WALK_TIME, model=model, motors="spec")
    recs = wm.records(out, AROUND)
    for row, world, tol in ((0, None, PATH_TOL), (1, worlds[1], WORLD_PATH_TOL)):
        dec: list = []
        nat = wr.walk(TINY, AROUND, nao, gaits, ctrl, max_time=WALK_TIME, model=model,
                      world=world, motors="spec", decisions=dec)
        rec = recs[row]
        assert rec["motors"] == nat["motors"] == "spec"
        a, b = np.asarray(nat["trajectory"]), np.asarray(rec["trajectory"])
        assert a.shape == b.shape and np.array_equal(a[:, 0], b[:, 0])
        assert np.max(np.linalg.norm(a[:, 1:3] - b[:, 1:3], axis=1)) < tol, row
        ours = wm.decisions(out, row)
        assert len(ours) == len(dec) >= 7
        for n, m in zip(dec, ours, strict=True):
            assert (n[0], n[1], n[3]) == (m[0], m[1], m[3])  # time, segment, mode
        assert rec["peak_current_frac"] == pytest.approx(nat["peak_current_frac"], abs=1e-3)
        assert rec["peak_current_frac"] <= 1.0 + 1e-5
        for key in ("success", "fell", "contact", "gait_switches"):
            assert rec[key] == nat[key], (row, key)
