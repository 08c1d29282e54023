"""Constraint-handling orders (penalty, Deb, epsilon), the epsilon schedule, gradient repair."""

import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.ops import constraints as ch
from eaco_jax.problems import ConstrainedProblem
from eaco_jax.problems.constrained import violation_of

F = jnp.array([5.0, 1.0, 3.0, -10.0, 0.0])
V = jnp.array([0.0, 0.0, 0.5, 2.0, 0.1])


def test_deb_rules_order():
    order = np.asarray(ch.rank_order(F, V, "deb"))
    # feasible first by f (1 then 0), then infeasible by violation (4: 0.1, 2: 0.5, 3: 2.0)
    assert order.tolist() == [1, 0, 4, 2, 3]
    assert bool(ch.better(1.0, 0.0, -100.0, 1e-9, "deb"))  # feasible beats infeasible
    assert bool(ch.better(9.0, 0.1, -9.0, 0.2, "deb"))  # smaller violation wins
    assert not bool(ch.better(2.0, 0.0, 1.0, 0.0, "deb"))


def test_epsilon_comparison():
    # with eps = 0.5, solutions 2 (v=0.5) and 4 (v=0.1) count as feasible
    order = np.asarray(ch.rank_order(F, V, "epsilon", epsilon=0.5))
    assert order.tolist() == [4, 1, 2, 0, 3]
    assert bool(ch.better(-1.0, 0.3, 0.0, 0.0, "epsilon", epsilon=0.5))
    assert not bool(ch.better(-1.0, 0.3, 0.0, 0.0, "epsilon", epsilon=0.1))
    # eps = 0 is Deb's rules
    np.testing.assert_array_equal(ch.rank_order(F, V, "epsilon", 0.0), ch.rank_order(F, V, "deb"))


def test_penalty_order():
    order = np.asarray(ch.rank_order(F, V, "penalty", penalty=10.0))
    np.testing.assert_array_equal(order, np.argsort(np.asarray(F + 10.0 * V), kind="stable"))


def test_unknown_method():
    with pytest.raises(ValueError, match="unknown constraint method"):
        ch.rank_order(F, V, "lagrange")


def test_epsilon_schedule():
    eps = [float(ch.epsilon_schedule(t, 2.0, 10.0, 5.0)) for t in range(0, 13)]
    assert eps[0] == pytest.approx(2.0)
    assert eps[5] == pytest.approx(2.0 * 0.5**5)
    assert all(a >= b for a, b in zip(eps, eps[1:], strict=False))
    assert eps[10] == 0.0 and eps[12] == 0.0
    v = jnp.array([0.0, 1.0, 2.0, 3.0, jnp.inf])
    assert float(ch.initial_epsilon(v, 0.5)) == 2.0


def test_equality_tolerance():
    assert float(violation_of(jnp.zeros(0), jnp.array([5e-5, -1e-4]))) == 0.0
    v = violation_of(jnp.array([0.5, -1.0]), jnp.array([3e-4]))
    assert float(v) == pytest.approx(0.5002, rel=1e-5)


def test_gradient_repair_reaches_feasibility():
    # unit circle (equality) and a half-plane (inequality)
    prob = ConstrainedProblem(
        lambda x: jnp.sum(x), lambda x: jnp.stack([0.2 - x[0]]),
        lambda x: jnp.stack([jnp.sum(x**2) - 1.0]), lower=[-2.0, -2.0], upper=[2.0, 2.0])
    x0 = jnp.array([-1.5, 1.7])
    assert float(prob.violation_one(x0)) > 0
    x, steps = ch.gradient_repair(prob, x0, 8, 0.0)
    assert float(prob.violation_one(x)) == 0.0
    assert 1 <= int(steps) <= 8
    x_same, n0 = ch.gradient_repair(prob, x, 8, 0.0)  # feasible ants are left alone
    np.testing.assert_array_equal(x_same, x)
    assert int(n0) == 0


def test_sqp_direction_is_one_newton_step_to_the_kkt_point():
    """A quadratic objective on a line (h = x0 + x1 - 1) is solved by one step, from a point
    where the inequality x1 <= 0.5 is near (active set) but pulls the wrong way (negative
    multiplier: dropped); the optimum is (2, 1) projected on the line, (1, 0)."""
    prob = ConstrainedProblem(
        lambda x: (x[0] - 2.0) ** 2 + (x[1] - 1.0) ** 2, lambda x: jnp.stack([x[1] - 0.5]),
        lambda x: jnp.stack([x[0] + x[1] - 1.0]), lower=[-5.0, -5.0], upper=[5.0, 5.0])
    x0 = jnp.array([0.3, 0.49])
    d = ch.sqp_direction(prob, x0, active_frac=0.05, margin_frac=0.0)
    np.testing.assert_allclose(np.asarray(x0 + d), [1.0, 0.0], atol=1e-5)
