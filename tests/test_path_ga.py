"""The path GA in the strategy contract: operators, ask/tell by hand, vmapped rates, checkpoints."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.ops.path_ops import mutate, random_walk
from eaco_jax.problems.path_planning import GOAL, START
from eaco_jax.problems.scenes import build_problem, random_scene
from eaco_jax.strategies import get
from eaco_jax.strategies.path_ga import PathGA, PathGAParams


@pytest.fixture(scope="module")
def scene():
    return build_problem(random_scene(5))


def test_random_walks_and_mutations_stay_valid_and_mutation_edits(scene):
    cost = scene.step_cost
    walks = jax.vmap(random_walk, in_axes=(0, None))(jax.random.split(jax.random.key(0), 64),
                                                     cost)
    t = np.asarray(scene.evaluate(walks))
    assert np.all(np.asarray(walks[:, 0]) == START) and np.isfinite(t).mean() > 0.9
    ok = walks[np.isfinite(t)]
    kids = jax.vmap(mutate, in_axes=(0, 0, None))(jax.random.split(jax.random.key(1), len(ok)),
                                                   ok, cost)
    kt = np.asarray(scene.evaluate(kids))
    assert np.all(np.isfinite(kt))  # an edit is kept only where its edges exist
    changed = np.any(np.asarray(kids) != np.asarray(ok), axis=1)
    assert changed.mean() > 0.5
    for k in np.asarray(kids):  # still simple: no node twice before the goal
        route = k[: int(np.argmax(k == GOAL)) + 1]
        assert len(set(route.tolist())) == len(route)


def test_ask_tell_by_hand_comes_near_the_optimum(scene):
    ga = PathGA(num_ants=32)
    state = ga.init(jax.random.key(0), scene)
    first, state = ga.ask(jax.random.key(1), state, scene)
    np.testing.assert_array_equal(first, state.pop)  # the initial population is evaluated first
    key = jax.random.key(2)
    sols = first
    initial = float(jnp.min(scene.evaluate(first)))
    for _ in range(150):
        state, metrics = ga.tell(state, sols, scene.evaluate(sols), scene)
        key, k = jax.random.split(key)
        sols, state = ga.ask(k, state, scene)
    assert float(state.best_cost) <= scene.optimum * 1.03 and float(state.best_cost) < initial
    assert int(state.evaluations) == 150 * 32
    assert float(jnp.min(state.pop_cost)) == float(state.best_cost)  # elitism keeps the best


def test_rates_matter_and_vmap(scene):
    """Rates are traced: a batch of settings runs in one vmapped call; with neither crossover
    nor mutation the GA only copies (the best never beats the initial population)."""
    ga = PathGA(num_ants=16)
    params = PathGAParams(p_crossover=jnp.array([0.0, 0.9]), p_mutation=jnp.array([0.0, 0.5]))

    def run(key, p):
        state = ga._init(key, scene, p)
        sols, state = ga._ask(key, state, scene)
        state, _ = ga._tell(state, sols, scene.evaluate(sols), scene)
        start = state.best_cost

        def body(carry, k):
            st, _ = carry
            s, st = ga._ask(k, st, scene)
            st, _ = ga._tell(st.replace(iteration=st.iteration + 1), s, scene.evaluate(s), scene)
            return (st, 0), None

        (state, _), _ = jax.lax.scan(body, (state, 0), jax.random.split(key, 60))
        return start, state.best_cost

    start, end = jax.jit(jax.vmap(run, in_axes=(None, 0)))(jax.random.key(3), params)
    assert float(end[0]) == float(start[0])
    assert float(end[1]) < float(start[1])


def test_minimize_checkpoint_resume_is_bit_identical(scene, tmp_path):
    """Through minimize's checkpoints, resumed after a "crash" at iteration 10 (later
    checkpoints deleted), the GA ends bit-identical to an unbroken run."""
    import shutil

    ga = get("path-ga", num_ants=16)
    kw = dict(seed=[0, 1], iterations=20, chunk_size=5)
    full = ea.minimize(scene, ga, **kw)
    ea.minimize(scene, ga, **kw, checkpointing=ea.Checkpointing(tmp_path, every=5, keep=10))
    for later in ("15", "20"):
        shutil.rmtree(tmp_path / later)
    resumed = ea.minimize(scene, ga, **kw, checkpointing=ea.Checkpointing(tmp_path, every=5))
    assert resumed.iterations == 20
    np.testing.assert_array_equal(np.asarray(resumed.best_cost), np.asarray(full.best_cost))
    np.testing.assert_array_equal(resumed.best_solution, full.best_solution)


def test_elitism_keeps_the_best_parent_when_every_child_dies(scene):
    ga = PathGA(num_ants=8, elites=1)
    state = ga.init(jax.random.key(0), scene)
    sols, state = ga.ask(jax.random.key(1), state, scene)
    costs = scene.evaluate(sols)
    state, _ = ga.tell(state, sols, costs, scene)
    dead = jnp.full_like(sols, START)  # never reaches the goal: +inf
    state, _ = ga.tell(state, dead, scene.evaluate(dead), scene)
    assert float(jnp.min(state.pop_cost)) == float(jnp.min(costs))
    assert np.isfinite(np.asarray(scene.evaluate(state.pop))).sum() == 1
