"""ContinuousEACO's finite-difference accounting beside its autodiff-charged evaluations."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import eaco_jax as ea
from eaco_jax.problems import ConstrainedProblem
from eaco_jax.strategies import ContinuousEACO


def problem() -> ConstrainedProblem:
    """n = 3, two inequalities (p + q = 2): f* = 1/3 at x = (1/3, 1/3, 1/3)."""
    return ConstrainedProblem(
        lambda x: jnp.sum(x**2),
        lambda x: jnp.array([1.0 - jnp.sum(x), x[0] - 2.0]),
        lower=[-2.0] * 3, upper=[2.0] * 3, name="acc", f_star=1.0 / 3.0)


def test_gradient_modes_charged_at_finite_difference_cost():
    prob = problem()
    n, functions, hessian = 3, 3, 4 * 5 // 2
    strat = ContinuousEACO(num_ants=6, archive_size=8, refine_ants=1, repair_steps=2)
    state = strat.init(jax.random.key(0), prob)
    key = jax.random.key(1)
    for _ in range(4):
        key, k = jax.random.split(key)
        before = state
        x, state = strat.ask(k, state, prob)
        taken = int(state.evaluations - before.evaluations) - (n + 1)  # repair steps
        assert taken >= 0
        assert int(state.fd_evaluations - before.fd_evaluations) == hessian + taken * (n + 1)
        assert int(state.fd_function_evaluations - before.fd_function_evaluations) == (
            functions * hessian + taken * (functions - 1) * (n + 1))
        state, _ = strat.tell(state, x, prob.evaluate(x), prob)
    assert int(state.fd_function_evaluations) > int(state.fd_evaluations) > int(
        state.evaluations)


def test_derivative_free_counts_agree_and_targets_are_recorded():
    strat = ContinuousEACO(num_ants=10, archive_size=12, refine_ants=0, repair_steps=0)
    easy = ConstrainedProblem(  # inactive constraint at the optimum x = 0.5: f* = 0
        lambda x: jnp.sum((x - 0.5) ** 2), lambda x: jnp.array([1.0 - jnp.sum(x)]),
        lower=[-2.0] * 3, upper=[2.0] * 3, name="easy", f_star=0.0)
    res = ea.minimize(easy, strat, seed=[0, 1], iterations=300, chunk_size=300)
    s = res.state
    np.testing.assert_array_equal(np.asarray(s.fd_evaluations), np.asarray(s.evaluations))
    np.testing.assert_array_equal(np.asarray(s.fd_function_evaluations),
                                  np.asarray(s.evaluations))
    te = np.asarray(s.target_evaluations)
    assert np.all(te > 0)
    np.testing.assert_array_equal(np.asarray(s.target_fd_evaluations), te)
    np.testing.assert_array_equal(np.asarray(s.target_fd_function_evaluations), te)
