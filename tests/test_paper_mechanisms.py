"""Each paper mechanism's effect on the pheromone matrix through GraphEACO.tell, against values
computed by hand here (plain numpy, not ops/pheromone.py), with alpha != 1 in Eq. 2 so that
the pheromone weight alpha is never confused with the global evaporation alpha_g of Eq. 71."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.ops.construction import choice_weights
from eaco_jax.problems.tsp import TSP
from eaco_jax.strategies.graph_eaco import GraphEACO, paper_params

N = 5
COORDS = np.array([[0, 0], [3, 0], [3, 4], [0, 4], [1, 2]], np.float64)
TOURS = np.array([[0, 1, 2, 3, 4], [0, 2, 1, 3, 4], [0, 1, 3, 2, 4]], np.int32)
LENGTHS = np.array([10.0, 12.0, 20.0], np.float32)  # given, not measured: tell trusts fitness
TAU = np.array([[0.1 * (1 + i + j) if i != j else 0.0 for j in range(N)] for i in range(N)],
               np.float32)
RHO, ALPHA_G, Q, SIGMA, ALPHA = 0.25, 0.3, 2.0, 2.0, 2.5
STRATEGY = GraphEACO(num_ants=3, local_search="none")
OFF = {k: jnp.bool_(False) for k in (
    "use_local_update", "use_global_update", "use_elitist", "use_deposit_condition",
    "use_adaptive_weight", "use_bounds", "use_chaos", "use_evaporation_schedule",
    "use_restart", "use_restart_best")}


@pytest.fixture(scope="module")
def problem():
    return TSP.from_coords(COORDS, name="five", neighbors=4)


def edges(tour) -> set[tuple[int, int]]:
    return {tuple(sorted((int(a), int(b)))) for a, b in zip(tour, np.roll(tour, -1), strict=True)}


def on(e, tour) -> bool:
    return tuple(sorted(e)) in edges(tour)


def tell(problem, iter_best=np.inf, l_pn=15.0, since=0, best=(None, np.inf), **switches):
    """tau after one tell from TAU with only ``switches`` on (alpha = 2.5 everywhere)."""
    params = STRATEGY.default_params(problem).replace(
        **OFF, alpha=jnp.float32(ALPHA), rho=jnp.float32(RHO), alpha_g=jnp.float32(ALPHA_G),
        q=jnp.float32(Q), sigma=jnp.float32(SIGMA), gb_every=jnp.float32(1.0),
        restart_after=jnp.float32(10.0), restart_branching=jnp.float32(0.0))
    params = params.replace(**{k: (jnp.bool_(v) if isinstance(v, bool) else jnp.float32(v))
                               for k, v in switches.items()})
    state = STRATEGY.init(jax.random.key(0), problem, params)
    best_tour, best_cost = best
    state = state.replace(
        tau=jnp.asarray(TAU), iter_best_cost=jnp.float32(iter_best),
        pheromone_tour_length=jnp.float32(l_pn), since_improvement=jnp.int32(since),
        best_cost=jnp.float32(best_cost),
        best_solution=jnp.asarray(TOURS[0] if best_tour is None else best_tour))
    new, metrics = STRATEGY.tell(state, jnp.asarray(TOURS), jnp.asarray(LENGTHS), problem)
    return np.asarray(new.tau), metrics, new


def pairs():
    return [(i, j) for i in range(N) for j in range(N) if i != j]


def test_local_update_eq68_70(problem):
    tau, _, _ = tell(problem, use_local_update=True)
    for i, j in pairs():
        dep = sum(Q / L for t, L in zip(TOURS, LENGTHS, strict=True) if on((i, j), t))
        used = any(on((i, j), t) for t in TOURS)
        want = (1 - RHO) * TAU[i, j] + RHO * dep if used else TAU[i, j]
        np.testing.assert_allclose(tau[i, j], want, rtol=1e-6, err_msg=str((i, j)))


def test_global_update_eq71_uses_alpha_g_not_alpha(problem):
    tau, _, new = tell(problem, use_global_update=True)
    assert float(new.best_cost) == 10.0
    for i, j in pairs():
        want = (1 - ALPHA_G) * TAU[i, j] + ALPHA_G * (1 / 10.0 if on((i, j), TOURS[0]) else 0)
        np.testing.assert_allclose(tau[i, j], want, rtol=1e-6, err_msg=str((i, j)))


def _elitist_want(weights, best=TOURS[0], l_best=10.0, rho=RHO):
    want = np.zeros_like(TAU)
    for i, j in pairs():
        colony = sum(w / 3 * Q / L for t, L, w in zip(TOURS, LENGTHS, weights, strict=True)
                     if on((i, j), t))
        elite = SIGMA * Q / l_best if on((i, j), best) else 0.0
        want[i, j] = (1 - rho) * TAU[i, j] + rho * (colony + elite)
    return want


def test_elitist_ants_eq73_74(problem):
    tau, _, _ = tell(problem, use_elitist=True)
    np.testing.assert_allclose(tau, _elitist_want([1, 1, 1]) + np.diag(np.diag(tau)),
                               rtol=1e-6)


def test_elitist_only_deposit_eq3_4(problem):
    # iteration improved (10 < 11): ants shorter than the mean 14 deposit (10 and 12)
    tau, _, _ = tell(problem, use_elitist=True, use_deposit_condition=True, iter_best=11.0)
    off_diag = ~np.eye(N, dtype=bool)
    np.testing.assert_allclose(tau[off_diag], _elitist_want([1, 1, 0])[off_diag], rtol=1e-6)
    # no improvement on the previous iteration's best (9): only the sigma elitist ants deposit
    tau, _, _ = tell(problem, use_elitist=True, use_deposit_condition=True, iter_best=9.0)
    np.testing.assert_allclose(tau[off_diag], _elitist_want([0, 0, 0])[off_diag], rtol=1e-6)


def test_adaptive_weight_eq5_6(problem):
    l_pn = 15.0
    tau, metrics, _ = tell(problem, use_elitist=True, use_adaptive_weight=True, l_pn=l_pn)
    w = [(1 / L) / (1 / L + 1 / l_pn) for L in LENGTHS]  # rho_n of Eq. 5
    off_diag = ~np.eye(N, dtype=bool)
    np.testing.assert_allclose(tau[off_diag], _elitist_want([2 * x for x in w])[off_diag],
                               rtol=1e-6)
    np.testing.assert_allclose(float(metrics["adaptive_rho"]), np.mean(w), rtol=1e-6)


def test_bounds_eq7(problem):
    tau, metrics, _ = tell(problem, use_global_update=True, use_bounds=True,
                           p_best=0.05, branching=0.0)
    tau_max = 1.0 / 10.0  # scale 1 (global update only) / L_best
    root = 0.05 ** (1 / N)
    tau_min = tau_max * (1 - root) / ((N / 2 - 1) * root)
    np.testing.assert_allclose(float(metrics["tau_max"]), tau_max, rtol=1e-6)
    np.testing.assert_allclose(float(metrics["tau_min"]), tau_min, rtol=1e-5)
    for i, j in pairs():
        raw = (1 - ALPHA_G) * TAU[i, j] + ALPHA_G * (0.1 if on((i, j), TOURS[0]) else 0)
        np.testing.assert_allclose(tau[i, j], np.clip(raw, tau_min, tau_max), rtol=1e-5)


def test_dynamic_evaporation_slows_local_and_global_rules(problem):
    # the best (5) is not improved: stagnation 24 -> 25 of a 50-iteration window, strength 0.5
    best = (TOURS[1], 5.0)
    rho_t = RHO * (1 - 0.5 * 25 / 50)
    tau, metrics, _ = tell(problem, use_local_update=True, use_global_update=True,
                           use_evaporation_schedule=True, since=24, best=best,
                           stagnation_window=50.0, evaporation_slowdown=0.5)
    np.testing.assert_allclose(float(metrics["rho_t"]), rho_t, rtol=1e-6)
    alpha_t = ALPHA_G * rho_t / RHO
    for i, j in pairs():
        dep = sum(Q / L for t, L in zip(TOURS, LENGTHS, strict=True) if on((i, j), t))
        used = any(on((i, j), t) for t in TOURS)
        local = (1 - rho_t) * TAU[i, j] + rho_t * dep if used else TAU[i, j]
        want = (1 - alpha_t) * local + alpha_t * (1 / 5.0 if on((i, j), TOURS[1]) else 0)
        np.testing.assert_allclose(tau[i, j], want, rtol=1e-6, err_msg=str((i, j)))


def test_restart_resets_to_tau_max(problem):
    tau, metrics, new = tell(problem, use_bounds=True, use_global_update=True,
                             use_restart=True, since=9, best=(TOURS[1], 5.0))
    assert int(new.restarts) == 1
    np.testing.assert_allclose(tau, np.full((N, N), 1 / 5.0), rtol=1e-6)


def test_eq2_weights_with_alpha_not_one():
    tau = jnp.asarray(TAU + np.eye(N, dtype=np.float32))
    d = np.hypot(*(COORDS[:, None, :] - COORDS[None, :, :]).transpose(2, 0, 1))
    log_eta = np.where(np.eye(N, dtype=bool), -np.inf, -np.log(np.maximum(d, 0.5)))
    w = np.asarray(choice_weights(tau, jnp.asarray(log_eta, jnp.float32), ALPHA, 3.0))
    raw = np.where(np.eye(N, dtype=bool), 0.0, TAU.astype(np.float64) ** ALPHA
                   * (1 / np.maximum(d, 0.5)) ** 3.0)
    want = raw / raw.max(axis=1, keepdims=True)
    np.testing.assert_allclose(w, want, rtol=1e-5)


def test_chaos_is_the_logistic_map_in_ask(problem):
    params = STRATEGY.default_params(problem).replace(use_chaos=jnp.bool_(True))
    state = STRATEGY.init(jax.random.key(3), problem, params)
    x = np.asarray(state.chaos, np.float64)
    _, after = STRATEGY.ask(jax.random.key(4), state, problem)
    np.testing.assert_allclose(np.asarray(after.chaos), 4 * x * (1 - x), rtol=1e-5)


def test_paper_preset_turns_every_mechanism_on(problem):
    p = GraphEACO(preset="paper").default_params(problem)
    same = GraphEACO().default_params(problem, preset="paper")
    leaves = zip(jax.tree.leaves(p), jax.tree.leaves(same), strict=True)
    assert all(bool(a == b) for a, b in leaves)
    for name in ("use_local_update", "use_global_update", "use_elitist", "use_deposit_condition",
                 "use_adaptive_weight", "use_bounds", "use_chaos", "use_evaporation_schedule"):
        assert bool(getattr(p, name)), name
    assert not bool(p.use_restart) and not bool(p.init_at_tau_max)
    np.testing.assert_allclose([float(p.beta), float(p.rho), float(p.q), float(p.q0),
                                float(p.p_crossover), float(p.p_mutation)],
                               [5.0, 0.2, 100.0, 0.8, 0.6, 0.5], rtol=1e-6)
    assert GraphEACO(preset="paper", local_search="none").crossover == "erx"
    assert paper_params().use_chaos
    mmas = GraphEACO(preset="mmas").default_params(problem)
    assert not bool(mmas.use_elitist) and bool(mmas.use_restart)


def test_without_bounds_trails_start_and_restart_finite(problem):
    """use_bounds=False must not start (or restart) the trails at tau_max = +inf."""
    params = STRATEGY.default_params(problem).replace(use_bounds=jnp.bool_(False))
    state = STRATEGY.init(jax.random.key(0), problem, params)
    assert np.all(np.isfinite(np.asarray(state.tau)))
    tau, _, new = tell(problem, use_global_update=True, use_restart=True, since=9,
                       best=(TOURS[1], 5.0))
    assert int(new.restarts) == 1 and np.all(np.isfinite(tau))
    np.testing.assert_allclose(tau, np.full((N, N), 1 / 5.0), rtol=1e-6)
