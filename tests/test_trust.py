"""Numbers the library reports are true: exact tour lengths, hard evaluation budgets, float64
feasibility re-checks, checked hyper-parameters, one-line errors for nonsense."""

from __future__ import annotations

import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.problems import TSP, ConstrainedProblem, load_tsplib
from eaco_jax.strategies.continuous_eaco import ContinuousEACO
from eaco_jax.strategies.graph_eaco import GraphEACO


# --------------------------------------------------------------------------- item 0: tours
def test_from_coords_keeps_real_distances_unless_a_rule_is_named():
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 1, (30, 2))
    real = TSP.from_coords(xy)
    assert not real.integer and 0.0 < float(real.dist[0, 1]) < 1.5
    tsplib = TSP.from_coords(xy, metric="EUC_2D")
    assert tsplib.integer and set(np.unique(np.asarray(tsplib.dist))) <= {0.0, 1.0}
    tour = np.arange(30)
    want = sum(np.hypot(*(xy[i] - xy[(i + 1) % 30])) for i in range(30))
    assert abs(real.evaluate(tour[None])[0] - want) < 1e-5 * want


def test_long_integer_tours_are_exact():
    """Integer edges summing past 2**24: float32 sums are off; the int32 path is exact."""
    rng = np.random.default_rng(1)
    n = 60
    d = rng.integers(500_000, 1_000_000, (n, n))
    d = np.triu(d, 1)
    d = d + d.T
    p = TSP.from_distance_matrix(d)
    tours = np.stack([rng.permutation(n) for _ in range(50)]).astype(np.int32)
    exact = np.array([d[t, np.roll(t, -1)].sum() for t in tours])
    assert exact.min() > 2**24
    np.testing.assert_array_equal(p.evaluate(tours), exact)  # host: float64, exact
    import jax

    traced = np.asarray(jax.jit(lambda q, t: q.evaluate(t))(p, tours), np.float64)
    np.testing.assert_array_equal(traced, exact.astype(np.float32))  # int32 sum, rounded once
    res = ea.minimize(p, GraphEACO(num_ants=4, local_search="none"), seed=0, iterations=3)
    t = res.best_solution
    assert res.best_cost == d[t, np.roll(t, -1)].sum()


def test_host_evaluate_refuses_non_tours():
    p = load_tsplib("eil51")
    with pytest.raises(ProblemError, match=r"shape \(m, 51\)"):
        p.evaluate(np.arange(50)[None])
    with pytest.raises(ProblemError, match="outside 0..50"):
        p.evaluate(np.r_[np.arange(50), 51][None])
    with pytest.raises(ProblemError, match="permutation"):
        p.evaluate(np.r_[np.arange(50), 0][None])
    with pytest.raises(ProblemError, match="2\\*\\*24"):
        TSP.from_distance_matrix(np.array([[0, 2**25, 1], [2**25, 0, 1], [1, 1, 0]]))


def test_huge_dimension_refused_before_allocating(tmp_path):
    f = tmp_path / "huge.tsp"
    f.write_text("NAME: huge\nTYPE: TSP\nDIMENSION: 2000000000\nEDGE_WEIGHT_TYPE: EUC_2D\n"
                 "NODE_COORD_SECTION\n1 0 0\n2 1 1\n3 2 2\nEOF\n")
    with pytest.raises(ProblemError, match="DIMENSION 2000000000 needs"):
        load_tsplib(str(f))
    folder = tmp_path / "folder.tsp"
    folder.mkdir()
    with pytest.raises(ProblemError, match="is a directory"):
        load_tsplib(str(folder))


# --------------------------------------------------------------------------- item 1: budgets
@pytest.mark.parametrize("budget", [300, 1000])
def test_max_evaluations_is_a_hard_cap_with_repair_and_refinement(budget):
    problem = ea.problems.cec2006("g06")
    s = ContinuousEACO(num_ants=10, archive_size=12)
    res = ea.minimize(problem, s, seed=[0, 1], max_evaluations=budget)
    assert np.all(res.evaluations <= budget)
    assert np.all(res.evaluations > budget - s.max_charge(problem))
    assert res.stop_reason == "max_evaluations" and res.max_evaluations == budget
    assert res.history["best_cost"].shape[1] == res.iterations


def test_budget_below_one_iteration_names_the_charge():
    with pytest.raises(ConfigError, match="repair up to 3 x 20"):
        ea.minimize(ea.problems.cec2006("g06"), max_evaluations=50)


# --------------------------------------------------------------------------- item 2: feasibility
def _vessel():
    def f(x):
        return (0.6224 * x[0] * x[2] * x[3] + 1.7781 * x[1] * x[2] ** 2
                + 3.1661 * x[0] ** 2 * x[3] + 19.84 * x[0] ** 2 * x[2])

    def g(x):
        return jnp.stack([-x[0] + 0.0193 * x[2], -x[1] + 0.00954 * x[2],
                          -jnp.pi * x[2] ** 2 * x[3] - 4.0 / 3.0 * jnp.pi * x[2] ** 3 + 1296000.0,
                          x[3] - 240.0])

    return ConstrainedProblem(f, g, lower=[0.0625, 0.0625, 10.0, 10.0],
                              upper=[6.1875, 6.1875, 200.0, 200.0], name="vessel")


def test_feasibility_is_rechecked_in_float64():
    res = ea.minimize(_vessel(), seed=0, max_evaluations=4000)
    assert res.precision == "float64"  # constraints: auto picks float64
    assert res.tolerance == {"inequality": 0.0, "equality": 1e-4}
    check = _vessel().host_check(res.x)
    assert res.feasible == check["feasible"] and res.f == check["f"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r32 = ea.minimize(_vessel(), seed=0, max_evaluations=4000, precision="float32")
    assert r32.precision == "float32"
    truth = _vessel().host_check(r32.x)
    assert bool(r32.feasible) == truth["feasible"] and float(r32.violation) == truth["violation"]
    claimed = float(r32.state.best_violation) <= 0
    warned = any("re-checked in float64" in str(w.message) for w in caught)
    assert warned == (claimed and not truth["feasible"])


def test_recheck_refutes_a_point_feasible_only_in_float32():
    """g(x) = x0 - 0.1 at x0 = float32(0.1): 0 in float32, +1.5e-9 in float64 (tolerance 0)."""
    p = ConstrainedProblem(lambda x: x[0] + x[1] ** 2, lambda x: jnp.stack([x[0] - 0.1]),
                           lower=[0.1, -1.0], upper=[1.0, 1.0], name="edge")
    x = np.float32([0.1, 0.0])
    assert float(p.evaluate(jnp.asarray(x)[None]).violation[0]) == 0.0  # float32 says feasible
    check = p.host_check(x)
    assert not check["feasible"] and check["cost"] == np.inf
    assert check["violation"] == float(np.float32(0.1)) - 0.1 > 0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r32 = ea.minimize(p, seed=0, max_evaluations=2000, precision="float32")
    assert float(r32.state.best_violation) == 0.0 and np.asarray(r32.x)[0] == np.float32(0.1)
    assert not r32.feasible and float(r32.violation) > 0
    assert any("re-checked in float64" in str(w.message) for w in caught)


def test_float64_problem_keeps_float64_outside_the_scope():
    with ea.problems.float64():
        p = ea.problems.cec2006("g06")
    res = ea.minimize(p, seed=0, max_evaluations=500)
    assert res.precision == "float64" and np.asarray(res.state.best_f).dtype == np.float64
    with pytest.raises(ConfigError, match="holds float64 arrays"):
        ea.minimize(p, seed=0, max_evaluations=500, precision="float32")


def test_all_nan_objective_is_an_error_naming_it():
    p = ConstrainedProblem(lambda x: jnp.nan * x[0], lower=[0.0, 0.0], upper=[1.0, 1.0],
                           name="broken")
    with pytest.raises(ProblemError, match="every evaluation of 'broken' returned NaN"):
        ea.minimize(p, seed=0, iterations=4)


def test_infinite_objective_everywhere_is_not_feasible_and_warns():
    p = ConstrainedProblem(lambda x: jnp.inf * (1.0 + x[0] ** 2), lower=[0.0, 0.0],
                           upper=[1.0, 1.0], name="flat")
    with pytest.warns(UserWarning, match="every evaluation of 'flat' returned inf") as caught:
        res = ea.minimize(p, seed=[0, 1], iterations=4)
    assert not np.any(res.feasible) and np.all(np.isinf(res.best_cost))
    assert np.all(np.asarray(res.violation) == 0.0)  # no constraint is violated: f is the fault
    assert not any("re-checked in float64" in str(w.message) for w in caught)
    assert not p.host_check(np.zeros(2))["feasible"]


# --------------------------------------------------------------------------- item 3: ranges
@pytest.mark.parametrize("field, value", [("rho", 1.5), ("q0", 1.5), ("alpha", -1.0),
                                          ("beta", float("nan")), ("use_chaos", 2)])
def test_graph_params_outside_their_range_are_one_line(field, value):
    s = GraphEACO(num_ants=4)
    p = load_tsplib("burma14")
    params = s.default_params(p).replace(**{field: value})
    with pytest.raises(ConfigError, match=f"GraphParams.{field}=.* outside its range") as err:
        ea.minimize(p, s, params=params, iterations=2)
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match=f"params\\[1\\]: GraphParams.{field}"):
        ea.minimize(p, s, params=[s.default_params(p), params], iterations=2)


def test_traced_params_stay_traced():
    """init under vmap gets tracers: nothing is checked (or concretised) there."""
    import jax

    s, p = GraphEACO(num_ants=4), load_tsplib("burma14")
    rhos = jnp.array([0.1, 0.2])
    states = jax.vmap(lambda r: s.init(jax.random.key(0), p, s.default_params(p).replace(
        rho=r)))(rhos)
    np.testing.assert_allclose(states.params.rho, rhos)


def _tsp_sweep(**extra):
    return {"command": "tsp", "args": {"instance": "burma14", "ants": 4, "iterations": 2,
                                       "local_search": "none"}, "seeds": 1, **extra}


def test_sweep_cells_checked_against_ranges_naming_the_cell():
    from eaco_jax.sweep import plan

    with pytest.raises(ConfigError, match=r"sweep cell 1 \{\"q0\": 1.5\}: GraphParams.q0=1.5 "
                                          r"is outside its range \[0, 1\]"):
        plan(_tsp_sweep(cells=[{"q0": 0.5}, {"q0": 1.5}]))
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['bogus_key'\]; valid: .*q0"):
        plan(_tsp_sweep(cells=[{"bogus_key": 1}]))
    with pytest.raises(ConfigError, match=r"sweep cell 0 .*q0='abc' is not a number"):
        plan(_tsp_sweep(cells=[{"q0": "abc"}]))
    with pytest.raises(ConfigError, match=r"sweep cell 0 .*ants='abc' must be an integer"):
        plan(_tsp_sweep(cells=[{"ants": "abc"}]))


def test_sweeping_an_unused_param_is_refused_naming_the_switch():
    from eaco_jax.sweep import plan

    with pytest.raises(ConfigError, match="'rho' has no effect in any cell: it acts only with "
                                          "use_local_update or use_elitist"):
        plan(_tsp_sweep(grid={"rho": [0.05, 0.2, 0.5]}))
    kind, cells = plan(_tsp_sweep(grid={"rho": [0.05, 0.2]}, args={
        "instance": "burma14", "ants": 4, "iterations": 2, "local_search": "none",
        "use_elitist": True}))
    assert len(cells) == 2 and all(c.params["use_elitist"] for c in cells)
    with pytest.warns(UserWarning, match="'rho' has no effect in 2 of 4 cells"):
        plan(_tsp_sweep(grid={"rho": [0.05, 0.2], "use_local_update": [False, True]}))


# --------------------------------------------------------------------------- the command line
def test_cli_version_info_params_and_budget_flags(tmp_path):
    import json

    from typer.testing import CliRunner

    from eaco_jax.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0 and res.output.strip() == f"eaco_jax {ea.__version__}"
    res = runner.invoke(app, ["info", "--json"])
    info = json.loads(res.output.strip().splitlines()[-1])
    assert info["eaco_jax"] == ea.__version__ and info["devices"]
    res = runner.invoke(app, ["--no-compile-cache", "tsp", "burma14", "--ants", "4",
                              "--local-search", "none", "--max-evaluations", "30", "--json",
                              "--params", "use_elitist=true,rho=0.3"])
    assert res.exit_code == 0, res.output
    record = json.loads(res.output.strip().splitlines()[-1])
    assert record["evaluations"] <= 30 and record["stop_reason"] == "max_evaluations"
    for bad, needle in ((["--seed", "99999999999999999999"], "outside its range 0..4294967295"),
                        (["--params", "q0=2"], "GraphParams.q0=2.0 is outside its range"),
                        (["--ants", "1000000000"], "the colony state needs")):
        res = runner.invoke(app, ["tsp", "eil51", *bad])
        assert res.exit_code == 2 and needle in res.output, res.output
        assert "Traceback" not in res.output


def test_capped_run_checkpoints_resume_cleanly(tmp_path):
    """The last, budget-cut chunk is saved with the iterations that ran: the finished run
    restores as finished (no 'corrupt' fallback) and equals an unbroken one."""
    problem, s = ea.problems.cec2006("g06"), ContinuousEACO(num_ants=10, archive_size=12)
    kw = dict(seed=[0, 1], max_evaluations=700, chunk_size=7)
    unbroken = ea.minimize(problem, s, **kw)
    ck = ea.Checkpointing(tmp_path, every=7)
    first = ea.minimize(problem, s, checkpointing=ck, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = ea.minimize(problem, s, checkpointing=ck, **kw)
    for r in (first, again):
        np.testing.assert_array_equal(r.best_cost, unbroken.best_cost)
        np.testing.assert_array_equal(r.evaluations, unbroken.evaluations)
        assert r.iterations == unbroken.iterations


# --------------------------------------------------------------------------- working sets
def test_tsp_colony_whose_iteration_does_not_fit_is_refused_up_front():
    """The state check alone let a colony through whose local search needs 100x its state."""
    from typer.testing import CliRunner

    from eaco_jax.cli import app
    from eaco_jax.driver.minimize import check_state_memory, memory_limit

    p = load_tsplib("pr1002")
    ants = memory_limit() // (1002 * 1712) + 1  # or-2opt on 20 candidates: ~1.7 kB a city
    s = GraphEACO(num_ants=ants, local_search="or-2opt")
    with pytest.raises(ConfigError, match=r"per iteration .* use fewer ants \(at most ~\d+\)"):
        check_state_memory(s, p, 1, s.default_params(p))
    res = CliRunner().invoke(app, ["tsp", "pr1002", "--ants", str(ants), "--ls-best-k",
                                   str(ants), "--local-search", "or-2opt", "--iterations", "1"])
    assert res.exit_code == 2 and "Traceback" not in res.output, res.output
    err = res.output.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "use fewer ants" in err[0]


def test_focused_search_is_charged_for_the_cities_it_scans():
    """A focused search (ls_focus_width) evaluates at most that many cities' moves a step: the
    estimate charged every city's, which refused 384 ants at 100,000 cities (an estimated 51
    GiB against a measured 0.7 GB peak for 96 ants)."""
    from eaco_jax.driver.memory import (
        GRAPH_ANT_CITY_BYTES,
        LS_CANDIDATE_BYTES,
        LS_CITY_BYTES,
        working_set_bytes,
    )

    p = load_tsplib("pr1002")
    k = int(p.neighbors.shape[-1])
    full = GraphEACO(num_ants=64, local_search="or-2opt", max_new_edges=8)
    focused = GraphEACO(num_ants=64, local_search="or-2opt", max_new_edges=8, ls_focus_width=32)
    n, m = 1002, 64
    assert working_set_bytes(full, p)[0] == m * n * (
        GRAPH_ANT_CITY_BYTES + LS_CITY_BYTES + LS_CANDIDATE_BYTES * k)
    assert working_set_bytes(focused, p)[0] == m * (
        n * (GRAPH_ANT_CITY_BYTES + LS_CITY_BYTES) + 32 * LS_CANDIDATE_BYTES * k)


def test_out_of_memory_in_a_chunk_is_one_line():
    """A real XLA RESOURCE_EXHAUSTED (a buffer of terabytes) inside the compiled chunk."""
    p = ConstrainedProblem(
        lambda x: jnp.cumsum(jnp.broadcast_to(x[0], (2**20, 2**19)), axis=0)[-1, 0],
        lower=[0.0, 0.0], upper=[1.0, 1.0], name="hungry")
    with pytest.raises(ConfigError, match="out of memory running .* 'hungry'.* use fewer ants "
                       "or a smaller batch/chunk") as err:
        ea.minimize(p, ContinuousEACO(num_ants=2, refine_ants=0), seed=0, iterations=1)
    assert "\n" not in str(err.value)


def test_large_continuous_problem_warns_and_refuses_by_its_hessians():
    from eaco_jax.driver.minimize import check_state_memory, memory_limit

    def sphere(dim):
        return ConstrainedProblem(lambda x: jnp.sum(x ** 2), lower=[-1.0] * dim,
                                  upper=[1.0] * dim, name="wide")

    s, lean = ContinuousEACO(), ContinuousEACO(refine_ants=0)
    p = sphere(4500)  # 14 float32 matrices of 4500^2: 1.1 GB
    with pytest.warns(UserWarning, match=r"'wide' needs ~1\.\d GiB per iteration .*4500 x 4500 "
                      r"Hessians.*ContinuousEACO\(refine_ants=0\)"):
        check_state_memory(s, p, 1, s.default_params(p))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_state_memory(lean, p, 1, lean.default_params(p))  # linear in dim: no word
    p = sphere(int((memory_limit() / 56) ** 0.5) + 1)
    with pytest.raises(ConfigError, match=r"more than half .* use ContinuousEACO\(refine_ants=0"):
        check_state_memory(s, p, 1, s.default_params(p))
