"""MAP-Elites (strategies/map_elites.py) on constructed archives and the Rastrigin-proj toy, and
the gait-library problem (problems/gait_library.py) on a tiny real rollout."""

from __future__ import annotations

import math
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax import strategies
from eaco_jax.problems.gait import body_frame_speeds
from eaco_jax.problems.qd import QDEvaluation, rastrigin_proj
from eaco_jax.strategies.map_elites import MAPElites, archive_metrics


def toy(dim: int = 4):
    return rastrigin_proj(dim)


def fresh(strategy: MAPElites, problem, seed: int = 0):
    return strategy.init(jax.random.PRNGKey(seed), problem)


def test_insertion_keeps_the_best_per_cell_strictly_first_on_ties_border_for_outside():
    """Grid 4 x 4 over [-5.12, 5.12]^2 (cells 2.56 wide). Constructed descriptors and costs:
    the best ant of a cell wins, the first on a tie, a worse ant never replaces an elite, an
    equal one neither (strictly better only), outside descriptors go to the border cell and
    non-finite costs or descriptors are never inserted."""
    prob = toy()
    s = MAPElites(num_ants=7, grid=(4, 4))
    st = fresh(s, prob)
    x = jnp.arange(7 * 4, dtype=jnp.float32).reshape(7, 4) / 10.0
    desc = jnp.asarray([[-5.0, -5.0], [-4.0, -4.0], [-3.0, -3.0],  # cell 0 (two) / 0 / 0
                        [1.0, 1.0],  # cell (2, 2) = 10
                        [9.0, -9.0],  # outside -> border cell (3, 0) = 12
                        [1.0, 1.0],  # cell 10, tie with ant 3 -> ant 3 stays (first)
                        [0.0, jnp.nan]])  # non-finite descriptor: never inserted
    cost = jnp.asarray([5.0, 3.0, 3.0, 2.0, 1.0, 2.0, 0.0])
    st, n = s.insert(st, x, QDEvaluation(f=cost, descriptors=desc), prob)
    c = np.asarray(st.archive_cost)
    assert int(n) == 3
    assert set(np.flatnonzero(np.isfinite(c))) == {0, 10, 12}
    assert c[0] == 3.0 and c[10] == 2.0 and c[12] == 1.0
    np.testing.assert_array_equal(np.asarray(st.archive_x)[0], np.asarray(x[1]))  # first tie
    np.testing.assert_array_equal(np.asarray(st.archive_x)[10], np.asarray(x[3]))
    np.testing.assert_array_equal(np.asarray(st.archive_desc)[12], [9.0, -9.0])
    # a second batch: equal cost does not replace, better does, inf never fills a cell
    st2, n2 = s.insert(st, x[:3] + 100.0, QDEvaluation(
        f=jnp.asarray([3.0, 2.5, jnp.inf]), descriptors=jnp.asarray(
            [[-5.0, -5.0], [1.0, 1.0], [5.0, 5.0]])), prob)
    c2 = np.asarray(st2.archive_cost)
    assert int(n2) == 0 and c2[0] == 3.0 and c2[10] == 2.0 and not np.isfinite(c2[15])
    st3, n3 = s.insert(st2, x[:1] + 100.0, QDEvaluation(
        f=jnp.asarray([2.9]), descriptors=jnp.asarray([[-5.0, -5.0]])), prob)
    assert int(n3) == 1 and np.asarray(st3.archive_cost)[0] == np.float32(2.9)
    np.testing.assert_array_equal(np.asarray(st3.archive_x)[0], np.asarray(x[0] + 100.0))


def test_coverage_qd_score_and_max_fitness_of_a_constructed_archive():
    cost = jnp.asarray([1.0, jnp.inf, 3.0, jnp.inf, -2.0])
    m = archive_metrics(cost, 10.0)
    assert float(m["coverage"]) == pytest.approx(3 / 5)
    assert float(m["qd_score"]) == pytest.approx((10 - 1) + (10 - 3) + (10 + 2))
    assert float(m["max_fitness"]) == pytest.approx(2.0)
    # through tell: the metrics and best_cost = -QD score of the archive after insertion
    prob = toy()
    s = MAPElites(num_ants=2, grid=(2, 2))
    st = fresh(s, prob)
    ev = QDEvaluation(f=jnp.asarray([4.0, 6.0]), descriptors=jnp.asarray([[-1.0, -1.0],
                                                                          [1.0, 1.0]]))
    st, met = s.tell(st, jnp.zeros((2, 4)), ev, prob)
    off = prob.qd_offset
    assert off == pytest.approx((20 + 5.12**2) * 4)
    assert float(met["coverage"]) == 0.5 and int(met["inserted"]) == 2
    assert float(met["qd_score"]) == pytest.approx((off - 4) + (off - 6), rel=1e-6)
    assert float(st.best_cost) == pytest.approx(-float(met["qd_score"]))
    assert float(met["max_fitness"]) == -4.0


def test_toy_cost_and_descriptor_and_the_offset_bounds_every_cost():
    prob = toy(4)
    x = jnp.asarray([[0.0, 0.0, 0.0, 0.0], [1.0, 3.0, -2.0, 0.0], [5.12, 5.12, 5.12, 5.12]])
    ev = prob.evaluate(x)
    np.testing.assert_allclose(np.asarray(ev.f)[:2], [0.0, 1.0 + 9.0 + 4.0], atol=1e-4)
    np.testing.assert_allclose(np.asarray(ev.descriptors), [[0, 0], [2.0, -1.0], [5.12, 5.12]],
                               atol=1e-6)
    rng = np.random.default_rng(0).uniform(-5.12, 5.12, (2000, 4)).astype(np.float32)
    assert float(jnp.max(prob.evaluate(jnp.asarray(rng)).f)) <= prob.qd_offset


def test_eaco_kernel_width_comes_from_the_neighbouring_elites():
    """variation='eaco': a coordinate on which the parent and all its filled neighbours agree
    has zero kernel width (with line_sigma = 0 it is copied exactly); the others move."""
    prob = toy(4)
    s = MAPElites(num_ants=64, grid=(4, 4), variation="eaco", radius=1)
    st = fresh(s, prob)
    base = jnp.asarray([1.0, 2.0, 3.0, 4.0])
    xs = jnp.stack([base, base.at[0].set(-1.0), base.at[0].set(0.0)])
    desc = jnp.asarray([[-4.0, -4.0], [-4.0, -1.0], [-1.0, -4.0]])  # cells 0, 1, 4: neighbours
    st, _ = s.insert(st, xs, QDEvaluation(f=jnp.ones(3), descriptors=desc), prob)
    st = st.replace(params=st.params.replace(line_sigma=jnp.float32(0.0)))
    x, _ = s.ask(jax.random.PRNGKey(3), st, prob)
    x = np.asarray(x)
    np.testing.assert_array_equal(x[:, 1:], np.broadcast_to(np.asarray(base[1:]), (64, 3)))
    assert np.std(x[:, 0]) > 0.1
    # the isoline baseline moves every coordinate
    iso = MAPElites(num_ants=64, grid=(4, 4), variation="isoline")
    xi, _ = iso.ask(jax.random.PRNGKey(3), st, prob)
    assert np.all(np.std(np.asarray(xi)[:, 1:], axis=0) > 1e-3)


def test_empty_archive_asks_uniformly_in_the_box_and_bounds_hold():
    prob = toy(4)
    s = MAPElites(num_ants=256, grid=(5, 5), variation="eaco")
    x, _ = s.ask(jax.random.PRNGKey(0), fresh(s, prob), prob)
    x = np.asarray(x)
    assert x.min() >= -5.12 and x.max() <= 5.12 and np.std(x) > 2.5


def test_seeds_vmapped_equal_separate_runs_and_eaco_beats_isoline_on_the_toy():
    prob = toy(8)
    s = MAPElites(num_ants=32, grid=(10, 10), variation="eaco")
    both = ea.minimize(prob, s, seed=[0, 1], iterations=30)
    for i, seed in enumerate((0, 1)):
        one = ea.minimize(prob, s, seed=seed, iterations=30)
        # the same archive (XLA fuses the batched program's sums differently: last bits)
        a, b = np.asarray(both.state.archive_cost)[i], np.asarray(one.state.archive_cost)
        np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b))
        np.testing.assert_allclose(a, b, rtol=1e-5)
        np.testing.assert_allclose(np.asarray(both.state.archive_x)[i],
                                   np.asarray(one.state.archive_x), rtol=1e-5, atol=1e-5)
    assert np.all(np.asarray(both.state.evaluations) == 30 * 32)
    # the colony kernel fills more of the toy's outer cells than iso+line at equal evaluations
    iso = ea.minimize(prob, strategies.get("map-elites", num_ants=32, grid=(10, 10)),
                      seed=[0, 1], iterations=30)
    cov = lambda r: np.isfinite(np.asarray(r.state.archive_cost)).mean(axis=1)  # noqa: E731
    assert np.all(cov(both) > cov(iso))


def test_checkpoint_resume_is_bit_identical(tmp_path):
    prob = toy(4)
    s = MAPElites(num_ants=16, grid=(6, 6), variation="eaco")
    kw = dict(seed=[0, 1], iterations=20, chunk_size=5)
    full = ea.minimize(prob, s, **kw)
    ea.minimize(prob, s, **kw, checkpointing=ea.Checkpointing(tmp_path, every=5, keep=10))
    for later in ("15", "20"):
        shutil.rmtree(tmp_path / later)
    resumed = ea.minimize(prob, s, **kw, checkpointing=ea.Checkpointing(tmp_path, every=5))
    assert resumed.iterations == 20
    for name in ("archive_x", "archive_cost", "archive_desc", "qd_score"):
        np.testing.assert_array_equal(np.asarray(getattr(resumed.state, name)),
                                      np.asarray(getattr(full.state, name)))


def test_bad_configurations_get_one_line():
    with pytest.raises(ea.ConfigError, match="variation"):
        MAPElites(variation="cma")
    with pytest.raises(ea.ConfigError, match="grid"):
        MAPElites(grid=(0, 3))
    with pytest.raises(ea.ConfigError, match="descriptors"):
        MAPElites(grid=(3, 3, 3)).init(jax.random.PRNGKey(0), toy())
    with pytest.raises(ea.ProblemError, match="quality-diversity"):
        MAPElites().init(jax.random.PRNGKey(0), ea.problems.get("sphere"))
    with pytest.raises(ea.ConfigError, match="QDEvaluation"):
        s = MAPElites(num_ants=2, grid=(2, 2))
        s.tell(fresh(s, toy()), jnp.zeros((2, 4)), jnp.zeros(2), toy())


def test_body_frame_speeds_of_a_constructed_arc():
    """A torso on a circle of radius 1 m at 0.5 rad/s, heading along the tangent: forward
    speed 0.5 m/s, lateral 0, whatever the turn; a fall at 1 s counts only the first second."""
    dt, n = 0.02, 200
    t = np.arange(n + 1) * dt
    th = 0.5 * t
    tr = np.zeros((n + 1, 7), np.float32)
    tr[:, 0], tr[:, 1], tr[:, 6] = np.sin(th), 1 - np.cos(th), th
    f, lat = body_frame_speeds(jnp.asarray(tr), dt, jnp.asarray(n * dt))
    assert float(f) == pytest.approx(0.5, rel=1e-3) and abs(float(lat)) < 5e-3
    tr2 = tr.copy()
    tr2[:, 6] = th + math.pi / 2  # torso facing outward-left: the motion is to its right
    f2, lat2 = body_frame_speeds(jnp.asarray(tr2), dt, jnp.asarray(1.0))
    assert abs(float(f2)) < 5e-3 and float(lat2) == pytest.approx(-0.5, rel=1e-3)
    tr3 = tr.copy()
    tr3[100:, 0] += 5.0  # a jump after the fall at 1 s does not count
    f3, _ = body_frame_speeds(jnp.asarray(tr3), dt, jnp.asarray(1.0))
    assert float(f3) == pytest.approx(0.5, rel=1e-3)


# --------------------------------------------------------------------------- the gait library
def test_gait_library_fitness_is_survival_then_speed_and_descriptors_are_world_means():
    """Constructed per-world measurements (2 gaits x 4 worlds): a gait that fell in one world
    scores 3/4 (no speed term); one that never fell scores 1 + its mean forward speed (never
    below 1: a backward gait gets no speed term); descriptors are the world means."""
    from eaco_jax.problems.gait_library import make_gait_library_problem

    prob = make_gait_library_problem(horizon=1.0, worlds=0, lateral_range=(-0.1, 0.1))
    res = {"fell": jnp.asarray([[0, 1, 0, 0], [0, 0, 0, 0]], bool),
           "forward_mps": jnp.asarray([[0.2, 0.1, 0.2, 0.3], [-0.1, -0.1, -0.2, 0.0]]),
           "turn_deg_s": jnp.asarray([[4.0, 8.0, 0.0, 0.0], [-10.0, -10.0, -10.0, -10.0]]),
           "lateral_mps": jnp.asarray([[0.0, 0.0, 0.04, 0.0], [0.01, 0.01, 0.01, 0.01]])}
    ev = prob.score(res)
    np.testing.assert_allclose(np.asarray(ev.f), [-0.75, -1.0], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(ev.descriptors),
                               [[0.2, 3.0, 0.01], [-0.1, -10.0, 0.01]], rtol=1e-5)
    res["fell"] = jnp.zeros((2, 4), bool)
    np.testing.assert_allclose(np.asarray(prob.score(res).f)[0], -1.2, rtol=1e-6)


def test_constrained_gait_library_fitness_puts_every_feasible_gait_first():
    """Constructed per-world measurements (3 gaits x 2 worlds): a gait meeting endurance,
    current, slip and falls in both worlds scores 1 + its mean forward speed, whatever its
    drift (the library asks for yaw); one 10 C over the winding limit in one world scores
    1 / (1 + 10 / (limit - ambient)); one that fell in one of two worlds 1 / (1 + 1/2)."""
    from eaco_jax.gait import quality as ql
    from eaco_jax.problems.gait_library import make_gait_library_problem

    prob = make_gait_library_problem(horizon=1.0, worlds=0, constrained=True)
    mm = ql.mo.motor_model(prob.gait.spec)
    limit, rise = float(np.min(mm.t_limit)), float(np.min(mm.t_limit - mm.t_ambient))
    nu = prob.gait.spec.nu
    hot = np.full((3, 2, nu), limit - 15.0, np.float32)
    hot[1, 1, 3] = limit + 10.0
    res = {"fell": jnp.asarray([[0, 0], [0, 0], [0, 1]], bool),
           "forward_mps": jnp.asarray([[0.2, 0.3], [0.2, 0.2], [0.1, 0.1]]),
           "turn_deg_s": jnp.zeros((3, 2)), "lateral_mps": jnp.zeros((3, 2)),
           "winding_10min_c": jnp.asarray(hot),
           "peak_current_max_frac": jnp.full((3, 2), 0.9),
           "distance_m": jnp.ones((3, 2)), "foot_slip_m": jnp.full((3, 2), 0.02),
           "drift_deg": jnp.full((3, 2), 40.0)}
    ev = prob.score(res)
    np.testing.assert_allclose(np.asarray(ev.f),
                               [-1.25, -1.0 / (1.0 + 10.0 / rise), -1.0 / 1.5], rtol=1e-5)
    assert prob.constraint_names == ("endurance", "current", "slip", "falls")


def test_a_tiny_real_gait_library_run():
    """4 NAO gaits x 2 iterations, 1 s, one optimisation world: every elite sits in the cell
    of its own measured descriptor and its fitness is in [0, 1 + speed]."""
    from eaco_jax.problems.gait_library import make_gait_library_problem

    prob = make_gait_library_problem(backend="native", horizon=1.0, worlds=1, seed=5)
    s = MAPElites(num_ants=4, grid=(3, 3), variation="eaco")
    res = ea.minimize(prob, s, seed=5, iterations=2)
    assert int(res.state.evaluations) == 8
    lib = s.library(res.state, prob)
    assert 1 <= len(lib["cell"]) <= 8
    np.testing.assert_array_equal(
        np.asarray(s.cell_index(jnp.asarray(lib["descriptor"]), prob)), lib["cell"])
    assert np.all(-lib["cost"] >= 0) and np.all(-lib["cost"] <= 1.5)


@pytest.mark.slow
def test_gait_library_fills_cells_and_its_qd_score_never_drops():
    from eaco_jax.problems.gait_library import make_gait_library_problem, validate

    prob = make_gait_library_problem(backend="native", horizon=2.0, worlds=2, seed=0)
    s = MAPElites(num_ants=16, grid=(6, 8), variation="eaco")
    res = ea.minimize(prob, s, seed=[0, 1], iterations=8)
    qd = np.asarray(res.history["qd_score"])
    assert np.all(np.diff(qd, axis=1) >= 0)  # history: (seeds, iterations)
    cov = np.isfinite(np.asarray(res.state.archive_cost)).sum(axis=1)
    assert np.all(cov >= 5)
    one = jax.tree.map(lambda a: a[0], res.state)
    lib = s.library(one, prob)
    v = validate(prob, lib["x"], trials=4, seed=0)
    assert v["fall_rate"].shape == (len(lib["cell"]),)
    assert np.all((v["fall_rate"] >= 0) & (v["fall_rate"] <= 1))
    assert np.all(np.isfinite(v["forward_mps"])) and np.all(np.isfinite(v["turn_deg_s"]))


def test_a_constrained_library_validates_each_cell_against_the_constraints():
    """3 NAO gaits, 1 s, one world, motor model on: the test-world violation is what the
    constraints' own normalisation makes of the reported worst-world values."""
    from eaco_jax.gait import constraints as gc
    from eaco_jax.gait import quality as ql
    from eaco_jax.problems.gait_library import make_gait_library_problem, validate

    prob = make_gait_library_problem(backend="native", horizon=1.0, worlds=1, seed=2,
                                     constrained=True)
    x = jax.random.uniform(jax.random.PRNGKey(3), (3, prob.dim), minval=prob.lower,
                           maxval=prob.upper)
    v = validate(prob, x, trials=2, seed=4, chunk=4)
    vals = {k: jnp.asarray(v[f"{k}_worst"]) for k in prob.constraint_names}
    g = gc.normalised(vals, ql.mo.motor_model(prob.gait.spec), 1.0, 2)
    np.testing.assert_allclose(v["violation"], np.asarray(gc.violation(g)), rtol=1e-5)
    assert v["violation"].shape == (3,) and np.all(v["violation"] >= 0)
    np.testing.assert_allclose(v["falls_worst"], 2 * v["fall_rate"])


def test_library_box_narrows_around_a_gait_but_keeps_the_free_commands(monkeypatch):
    """experiments/gait_library.py --init GAIT --free ...: every parameter but the free ones
    is narrowed around the stored gait (eaco gait --init's box); the free ones keep the whole
    range; an unknown free name is refused."""
    import argparse
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    monkeypatch.syspath_prepend(str(root / "experiments"))
    import gait_library as gl

    init = root / "experiments/results/nao_constrained_warp/flat_r32/best_gait.json"
    args = argparse.Namespace(backend="native", horizon=1.0, worlds=1, speed_range=[-0.1, 0.3],
                              yaw_range=[-30.0, 30.0], constrained=True, init=init,
                              free=["step_length", "turn_rate"], target_noise=0.000443,
                              track_turn=False)
    full = gl.make_gait_library_problem(backend="native", horizon=1.0, worlds=1)
    prob = gl.library_problem(args)
    assert prob.constrained and prob.gait.robust.target_noise == 0.000443
    names = list(prob.param_names)
    lo, hi = np.asarray(prob.lower), np.asarray(prob.upper)
    flo, fhi = np.asarray(full.lower), np.asarray(full.upper)
    for n in ("step_length", "turn_rate"):
        i = names.index(n)
        assert lo[i] == flo[i] and hi[i] == fhi[i]
    for n in ("hip_height", "period", "direction"):
        i = names.index(n)
        assert flo[i] <= lo[i] < hi[i] <= fhi[i]
        assert hi[i] - lo[i] < 0.31 * (fhi[i] - flo[i])
    args.free = ["stride"]
    with pytest.raises(SystemExit, match="stride"):
        gl.library_problem(args)


def test_library_experiment_runs_one_seed_as_it_runs_several(monkeypatch):
    """experiments/gait_library.py's ``run_ours``: ``minimize`` returns one seed's state without
    the seed axis, and the experiment still gives one row and a state with that axis (the
    validation indexes it by seed)."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    monkeypatch.syspath_prepend(str(root / "experiments"))
    import gait_library as gl

    prob = gl.rastrigin_proj(4)
    rows, state, _ = gl.run_ours(prob, "eaco", (4, 4), 8, 3, [5], gl.MAPElitesParams())
    assert [r["seed"] for r in rows] == [5] and rows[0]["evaluations"] == 24
    assert np.asarray(state.archive_cost).shape == (1, 16)
    two, state2, _ = gl.run_ours(prob, "eaco", (4, 4), 8, 3, [5, 6], gl.MAPElitesParams())
    np.testing.assert_array_equal(np.asarray(state.archive_cost)[0],
                                  np.asarray(state2.archive_cost)[0])
