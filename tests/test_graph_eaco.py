"""GraphEACO: the colony end to end on small TSPLIB instances."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.ops import pheromone
from eaco_jax.problems.tsp import load_tsplib
from eaco_jax.strategies import GraphEACO

SMALL = GraphEACO(num_ants=8)


@pytest.fixture(scope="module")
def burma():
    return load_tsplib("burma14")


def _is_perm(tours) -> bool:
    tours = np.asarray(tours)
    return bool(np.all(np.sort(tours, axis=-1) == np.arange(tours.shape[-1])))


def _all_on(params):
    on = {f.name: jnp.bool_(True) for f in dataclasses.fields(params) if f.name.startswith("use_")}
    return params.replace(**on, q0=jnp.float32(0.3))


@pytest.mark.parametrize("all_mechanisms", [False, True])
def test_ask_tell_loop_keeps_permutations_and_bounds(burma, all_mechanisms):
    params = SMALL.default_params(burma)
    if all_mechanisms:
        params = _all_on(params)
    state = SMALL.init(jax.random.key(0), burma, params)
    key = jax.random.key(1)
    for _ in range(12):
        key, k = jax.random.split(key)
        tours, state = SMALL.ask(k, state, burma)
        assert tours.shape == (8, 14) and _is_perm(tours)
        state, metrics = SMALL.tell(state, tours, burma.evaluate(tours), burma)
        tau = np.asarray(state.tau)
        assert np.all(tau >= float(metrics["tau_min"]) * (1 - 1e-6))
        assert np.all(tau <= float(metrics["tau_max"]) * (1 + 1e-6))
        np.testing.assert_allclose(tau, tau.T)
        assert 0.0 <= float(metrics["diversity"]) <= 1.0
    assert _is_perm(state.best_solution[None])
    assert float(state.best_cost) == float(burma.evaluate(state.best_solution[None])[0])


def test_pheromone_greedy_tour_and_eq5_weight(burma):
    """Eq. 6: with pheromone high on one tour, the greedy-pheromone ant rebuilds it (L_pn);
    Eq. 5: the recorded adaptive weight is the mean of L_n^-1 / (L_n^-1 + L_pn^-1)."""
    params = SMALL.default_params(burma).replace(use_adaptive_weight=jnp.bool_(True))
    state = SMALL.init(jax.random.key(2), burma, params)
    marked = np.array([0, 5, 2, 9, 13, 1, 7, 3, 11, 4, 12, 6, 10, 8], np.int32)
    tau = pheromone.edge_sum(jnp.asarray(marked)[None], jnp.ones(1), 14) * 0.9 + 0.01
    state = state.replace(tau=tau)
    tours, state = SMALL.ask(jax.random.key(3), state, burma)
    l_pn = float(burma.evaluate(jnp.asarray(marked)[None])[0])
    assert float(state.pheromone_tour_length) == l_pn
    lengths = burma.evaluate(tours)
    state, metrics = SMALL.tell(state, tours, lengths, burma)
    want = np.mean((1 / np.asarray(lengths)) / (1 / np.asarray(lengths) + 1 / l_pn))
    np.testing.assert_allclose(float(metrics["adaptive_rho"]), want, rtol=1e-5)


def test_finds_burma14_optimum(burma):
    res = ea.minimize(burma, SMALL, seed=0, iterations=20, chunk_size=10)
    assert res.best_cost == burma.optimum
    assert _is_perm(res.best_solution[None])
    assert np.all(np.diff(res.history["best_cost"]) <= 0)


def test_seeds_reproducible_distinct_and_vmapped_equals_looped(burma):
    """Seed 1 run alone and as row 0 of a vmapped [1, 2] run (two separately compiled runs)
    must agree exactly, seed 2 likewise, and the two seeds must differ."""
    strat = GraphEACO(num_ants=8, local_search="none", crossover="none", mutation="none")
    kw = dict(iterations=8, chunk_size=8)
    a = ea.minimize(burma, strat, seed=1, **kw)
    b = ea.minimize(burma, strat, seed=2, **kw)
    assert not np.array_equal(a.history["iter_mean_cost"], b.history["iter_mean_cost"])
    both = ea.minimize(burma, strat, seed=[1, 2], **kw)
    for row, single in enumerate((a, b)):
        for key in ("iter_mean_cost", "best_cost", "diversity"):
            np.testing.assert_array_equal(both.history[key][row], single.history[key])
        np.testing.assert_array_equal(both.best_solution[row], single.best_solution)


def test_default_strategy_on_eil51_via_minimize():
    res = ea.minimize(load_tsplib("eil51"), seed=0, iterations=5, chunk_size=5)
    assert isinstance(res.strategy, GraphEACO)
    assert _is_perm(res.best_solution[None]) and res.best_solution.shape == (51,)
    assert 426 <= float(res.best_cost) < 426 * 1.1
    assert res.history["diversity"].shape == (5,)


def test_bad_static_config_is_a_clear_error():
    with pytest.raises(ValueError, match="local_search"):
        GraphEACO(local_search="3opt")
    with pytest.raises(ValueError, match="crossover"):
        GraphEACO(crossover="ox")


def _tell_round(strat, state, key):
    problem = load_tsplib("burma14")
    tours, state = strat.ask(key, state, problem)
    state, metrics = strat.tell(state, tours, problem.evaluate(tours), problem)
    return state, metrics, tours


def test_restart_waits_for_converged_trails_and_tracks_restart_best(burma):
    """MMAS restarts (ACOTSP): with ``restart_branching`` the trails are reset only once the
    lambda-branching factor is below it; the restart-best record follows the iteration bests
    and is cleared by a restart. Without the convergence test, restarts come every
    ``restart_after`` iterations."""
    strat = GraphEACO(num_ants=8, local_search="none")
    base = strat.default_params(burma).replace(restart_after=jnp.float32(1.0))
    runs = {}
    for gate in (0.0, 1e-6, 1.00001):
        params = base.replace(restart_branching=jnp.float32(gate))
        state = strat.init(jax.random.key(0), burma, params)
        rb = np.inf
        key = jax.random.key(1)
        for _ in range(30):
            key, k = jax.random.split(key)
            restarts = int(state.restarts)
            state, metrics, tours = _tell_round(strat, state, k)
            it_best = float(np.min(np.asarray(burma.evaluate(tours))))
            rb = min(rb, it_best)
            if int(state.restarts) > restarts:
                assert float(state.restart_best_cost) == np.inf
                assert gate == 0.0 or float(metrics["branching_factor"]) < gate
                rb = np.inf
            else:
                assert float(state.restart_best_cost) == rb
        runs[gate] = int(state.restarts)
    assert runs[1e-6] == 0  # the factor is never below 1e-6: never converged
    assert runs[0.0] > runs[1.00001]  # restarts every stagnant iteration without the test


def test_genetic_operators_auto_follow_local_search():
    """"auto" ERX / inversion: on with 2-opt, off without; an explicit choice is kept."""
    assert (GraphEACO().crossover, GraphEACO().mutation) == ("erx", "inversion")
    bare = GraphEACO(local_search="none")
    assert (bare.crossover, bare.mutation) == ("none", "none")
    assert GraphEACO(local_search="none", crossover="pmx").crossover == "pmx"


def test_mmas_preset_with_local_search_is_acotsps():
    """preset="mmas" with local search: ACOTSP's MMAS + LS settings (acotsp.c): tau_min =
    tau_max / (2 n), a restart of converged trails after 250 iterations without a better
    restart-best tour, no crossover or mutation; "default" keeps its own values."""
    from eaco_jax.errors import ConfigError

    problem = load_tsplib("pcb442")
    s = GraphEACO(local_search="2opt+oropt", preset="mmas")
    assert (s.crossover, s.mutation) == ("none", "none")
    p = s.default_params(problem)
    tau_max, tau_min = pheromone.mmas_bounds(jnp.float32(50778.0), problem.n, p.p_best, 1.0,
                                             p.branching)
    np.testing.assert_allclose(float(tau_min), float(tau_max) / (2 * problem.n), rtol=1e-5)
    assert float(p.restart_after) == 250.0 and p.restart_branching == np.float32(1.00001)
    assert bool(p.use_restart_best)
    d = GraphEACO(local_search="2opt+oropt").default_params(problem)
    assert float(d.branching) == 0.0 and float(d.restart_after) == 50.0
    assert GraphEACO(local_search="2opt+oropt").crossover == "erx"
    with pytest.raises(ConfigError, match="needs the problem"):
        s.default_params()
