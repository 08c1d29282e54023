"""Path planning among obstacles: visibility graph geometry, operators, colony vs Dijkstra."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.path_planning import GOAL, START, PathPlanning, random_environment
from eaco_jax.strategies.path_eaco import PathEACO, common_node_crossover, shortcut

SQUARE = [[4, 4], [6, 4], [6, 6], [4, 6]]


def _one_block():
    return PathPlanning.from_obstacles([SQUARE], start=[0, 5], goal=[10, 5], clearance=0.5)


def test_visibility_graph_blocks_through_obstacle_and_optimum_is_exact():
    p = _one_block()
    d = np.asarray(p.dist)
    assert not np.isfinite(d[START, GOAL])  # straight line passes through the square
    # optimum: start -> grown corner (3.5, 3.5) or (3.5, 6.5) -> other corner -> goal
    corner = np.hypot(3.5, 1.5)
    assert p.optimum == pytest.approx(2 * corner + 3.0, rel=1e-6)
    assert np.allclose(d, d.T)


def test_bad_environments_raise_clear_errors():
    with pytest.raises(ProblemError, match="inside obstacle"):
        PathPlanning.from_obstacles([SQUARE], start=[5, 5], goal=[10, 5])
    with pytest.raises(ProblemError, match="not convex"):
        PathPlanning.from_obstacles([[[0, 0], [4, 0], [1, 1], [0, 4]]], [9, 9], [8, 9])
    with pytest.raises(ProblemError, match="cannot be reached"):
        ring = [[[7, 7], [13, 7], [13, 8], [7, 8]], [[7, 12], [13, 12], [13, 13], [7, 13]],
                [[7, 7], [8, 7], [8, 13], [7, 13]], [[12, 7], [13, 7], [13, 13], [12, 13]]]
        PathPlanning.from_obstacles(ring, [0, 0], [10, 10])  # goal walled in


def test_evaluate_rejects_blocked_and_unfinished_paths():
    p = _one_block()
    n = p.n
    direct = jnp.full((n,), GOAL, jnp.int32).at[0].set(START)  # blocked straight line
    stuck = jnp.full((n,), 2, jnp.int32).at[0].set(START)  # never reaches the goal
    costs = p.evaluate(jnp.stack([direct, stuck]))
    assert np.all(np.isinf(np.asarray(costs)))


def test_shortcut_never_lengthens_and_crossover_keeps_endpoints():
    p = random_environment(15, seed=2, radius=(0.03, 0.06))
    strat = PathEACO(num_ants=16)
    state = strat.init(jax.random.key(0), p)
    paths = strat._walk(jax.random.key(1), state, p)
    cut = jax.vmap(shortcut, in_axes=(0, None))(paths, p.dist)
    before, after = np.asarray(p.evaluate(paths)), np.asarray(p.evaluate(cut))
    ok = np.isfinite(before)
    assert ok.any() and np.all(after[ok] <= before[ok] + 1e-4)
    keys = jax.random.split(jax.random.key(2), 16)
    kids = jax.vmap(common_node_crossover)(keys, paths, paths[::-1])
    assert np.all(np.asarray(kids[:, 0]) == START)
    both = ok & ok[::-1]
    assert np.all(np.asarray(kids)[both, -1] == GOAL)


def test_colony_reaches_dijkstra_optimum_and_is_reproducible():
    p = random_environment(12, seed=4, radius=(0.03, 0.06))
    a = ea.minimize(p, PathEACO(num_ants=16), seed=0, iterations=40)
    b = ea.minimize(p, PathEACO(num_ants=16), seed=0, iterations=40)
    np.testing.assert_array_equal(a.history["best_cost"], b.history["best_cost"])
    assert float(a.best_cost) <= p.optimum * 1.01
    assert np.isclose(float(p.evaluate(jnp.asarray(a.best_solution)[None])[0]), a.best_cost)
