"""The strategy contract and the minimize driver, on a tiny random-search strategy."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

import eaco_jax as ea
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import State, Strategy, base_fields, record_best


@struct.dataclass
class Sphere:
    lower: jax.Array
    upper: jax.Array
    kind: str = struct.field(pytree_node=False, default="continuous")
    name: str = struct.field(pytree_node=False, default="sphere")

    def evaluate(self, x):
        return Evaluation(f=jnp.sum(x**2, axis=-1), violation=jnp.zeros(x.shape[0]))


@struct.dataclass
class RSParams:
    scale: jax.Array


@struct.dataclass
class RSState(State):
    lower: jax.Array
    upper: jax.Array


@dataclasses.dataclass(frozen=True)
class RandomSearch(Strategy):
    num_ants: int = 8

    def default_params(self, problem):
        return RSParams(scale=jnp.float32(1.0))

    def _init(self, key, problem, params):
        return RSState(**base_fields(key, params, jnp.zeros_like(problem.lower)),
                       lower=problem.lower, upper=problem.upper)

    def _ask(self, key, state):
        x = jax.random.uniform(key, (self.num_ants, state.lower.shape[0]),
                               minval=state.lower, maxval=state.upper)
        return x * state.params.scale, state

    def scalar_cost(self, fitness):
        return fitness.f

    def _tell(self, state, solutions, fitness):
        return record_best(state, solutions, fitness.f)


def _problem():
    return Sphere(lower=-jnp.ones(3), upper=jnp.ones(3))


def test_minimize_runs_and_records_history():
    res = ea.minimize(_problem(), RandomSearch(), seed=1, iterations=25, chunk_size=10)
    assert res.iterations == 25
    assert int(res.evaluations) == 25 * 8
    assert res.history["best_cost"].shape == (25,)
    assert np.all(np.diff(res.history["best_cost"]) <= 0)
    assert np.isclose(res.best_cost, np.sum(res.best_solution**2), rtol=1e-5)


def test_same_seed_same_result_and_chunking_irrelevant():
    a = ea.minimize(_problem(), RandomSearch(), seed=3, iterations=20, chunk_size=20)
    b = ea.minimize(_problem(), RandomSearch(), seed=3, iterations=20, chunk_size=7)
    c = ea.minimize(_problem(), RandomSearch(), seed=4, iterations=20)
    np.testing.assert_array_equal(a.history["best_cost"], b.history["best_cost"])
    assert not np.array_equal(a.history["best_cost"], c.history["best_cost"])


def test_vmapped_seeds_equal_looped_seeds():
    batch = ea.minimize(_problem(), RandomSearch(), seed=[5, 6, 7], iterations=12)
    assert batch.history["best_cost"].shape == (3, 12)
    for i, s in enumerate([5, 6, 7]):
        one = ea.minimize(_problem(), RandomSearch(), seed=s, iterations=12)
        np.testing.assert_allclose(batch.history["best_cost"][i], one.history["best_cost"],
                                   rtol=1e-6)
