"""Continuous EACO: bounds, the public minimize API on a user problem, sweeps, CEC2006."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax
from eaco_jax.driver.minimize import minimize
from eaco_jax.problems import ConstrainedProblem, cec2006, float64, rastrigin
from eaco_jax.strategies import ContinuousEACO, ContinuousParams


def user_problem():
    """min (x0-1)^2 + (x1-2)^2 + x2^2  s.t.  x0 + x1 <= 1,  x2 = x0 - 0.5;  f* = 13/6."""
    return ConstrainedProblem(
        lambda x: (x[0] - 1) ** 2 + (x[1] - 2) ** 2 + x[2] ** 2,
        inequality=lambda x: jnp.stack([x[0] + x[1] - 1.0]),
        equality=lambda x: jnp.stack([x[2] - x[0] + 0.5]),
        lower=[-3.0, -3.0, -3.0], upper=[3.0, 3.0, 3.0], name="user", f_star=13 / 6,
    )


def test_user_problem_solved_through_public_api():
    # optimum: x1 = 1 - x0, x2 = x0 - 0.5, 6 x0 - 1 = 0 -> x0 = 1/6, f = 13/6
    prob = user_problem()
    res = eaco_jax.minimize(prob, seed=[0, 1], max_evaluations=3000, chunk_size=150)
    assert res.feasible.all()
    np.testing.assert_allclose(res.f, 13 / 6, atol=2e-3)
    np.testing.assert_allclose(res.x[:, 0] + res.x[:, 1], 1.0, atol=1e-3)
    assert {"best_f", "best_violation", "evaluations"} <= set(res.history)
    assert res.history["best_f"].shape[0] == 2


def test_ants_stay_in_bounds_with_every_operator_on():
    prob = rastrigin(4, bound=2.0)
    strat = ContinuousEACO(num_ants=16, archive_size=10, refine_ants=0)
    params = ContinuousParams(p_crossover=1.0, p_mutation=1.0, laplace_b=3.0, power_index=0.5,
                              chaos_rate=1.0, chaos_strength=2.0, chaos_patience=0.0, rho=5.0)
    state = strat.init(jax.random.key(0), prob, params)
    key = jax.random.key(1)
    for _ in range(5):
        key, k = jax.random.split(key)
        x, state = strat.ask(k, state, prob)
        assert bool(jnp.all((x >= prob.lower) & (x <= prob.upper)))
        state, _ = strat.tell(state, x, prob.evaluate(x), prob)


def test_params_are_vmappable():
    prob = user_problem()
    strat = ContinuousEACO(num_ants=8, archive_size=8)
    params = jax.tree.map(lambda a, b: jnp.stack([jnp.asarray(a), jnp.asarray(b)]),
                          ContinuousParams(q0=0.2), ContinuousParams(q0=0.9))
    states = jax.vmap(lambda p: strat.init(jax.random.key(0), prob, p))(params)
    assert states.archive_x.shape == (2, 8, 3)
    np.testing.assert_allclose(states.params.q0, [0.2, 0.9])


def test_other_constraint_methods_run():
    # without refinement and with one repair step: these only check the orders run end to end
    for method in ("deb", "penalty"):
        strat = ContinuousEACO(constraint_method=method, refine_ants=0, repair_steps=1)
        res = minimize(user_problem(), strat, seed=0, max_evaluations=1000, chunk_size=50)
        assert np.isfinite(res.f)
        if method == "deb":
            assert bool(res.feasible)


def test_bad_configuration():
    with pytest.raises(ValueError, match="constraint method"):
        ContinuousEACO(constraint_method="nope")
    with pytest.raises(ValueError, match="refine_ants"):
        ContinuousEACO(num_ants=2, refine_ants=4)


def test_g13_small_run_hits_target():
    with float64():
        # 25,000 charged (repair and refinement included) ~ the 10,000-iteration-budget of old
        res = minimize(cec2006("g13"), seed=[0, 1, 2, 3], max_evaluations=25_000,
                       chunk_size=150)
    assert res.feasible.all()
    assert np.all(res.f - 0.053941514041898 <= 1e-4)
    te = np.asarray(res.state.target_evaluations)
    assert np.all((0 < te) & (te <= np.asarray(res.evaluations)))


def test_external_evaluator_drives_ask_tell():
    """The problem's own objective is a dummy; a numpy evaluator outside JAX supplies the
    fitness through tell, and the colony minimises *that* (init evaluates nothing)."""
    dummy = ConstrainedProblem(lambda x: jnp.sum(x) * 0.0 + 53.4, lower=[-2.0] * 3,
                               upper=[2.0] * 3, name="external")
    strat = ContinuousEACO(num_ants=10, archive_size=12, refine_ants=0, repair_steps=0)
    state = strat.init(jax.random.key(0), dummy)
    assert not np.isfinite(float(state.best_f))  # nothing evaluated yet

    def numpy_objective(x):  # (m, 3) -> (m,), shifted sphere, minimum 0 at (1, -1, 0.5)
        return np.sum((np.asarray(x, np.float64) - [1.0, -1.0, 0.5]) ** 2, axis=1)

    key = jax.random.key(1)
    for _ in range(150):
        key, k = jax.random.split(key)
        x, state = strat.ask(k, state, dummy)
        f = numpy_objective(x)
        fitness = eaco_jax.Evaluation(f=jnp.asarray(f, jnp.float32),
                                      violation=jnp.zeros(len(f), jnp.float32))
        state, metrics = strat.tell(state, x, fitness, dummy)
    assert float(state.best_f) < 1e-3
    np.testing.assert_allclose(np.asarray(state.best_solution), [1.0, -1.0, 0.5], atol=0.05)
    assert float(metrics["best_f"]) == float(state.best_f)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["g01", "g09", "g10", "g13"])
def test_cec2006_four_seeds(name):
    with float64():
        res = minimize(cec2006(name), seed=[0, 1, 2, 3], max_evaluations=100_000)
    te = np.asarray(res.state.target_evaluations)
    assert (te > 0).all() and (te <= 100_000).all()


def test_non_differentiable_problem_gets_gradient_free_colony():
    """A simulator-like objective (pure_callback, no derivatives) runs through minimize."""
    import numpy as np_

    def host(x):
        return np_.sum(np_.asarray(x) ** 2, axis=-1).astype(np_.float32)

    def objective(x):
        return jax.pure_callback(host, jax.ShapeDtypeStruct((), jnp.float32), x,
                                 vmap_method="broadcast_all")

    prob = ConstrainedProblem(objective, lower=[-1.0, -1.0], upper=[1.0, 1.0], name="sim",
                              differentiable=False)
    res = eaco_jax.minimize(prob, seed=0, iterations=30)
    assert float(res.f) < 0.05
    with pytest.raises(ValueError, match="refine_ants=0"):
        ContinuousEACO().init(jax.random.key(0), prob)
