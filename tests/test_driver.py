"""The strategy contract and the minimize driver, on a tiny random-search strategy."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

import eaco_jax as ea
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import State, Strategy, as_params, base_fields, record_best


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
    scale: jax.Array = 1.0


@dataclasses.dataclass(frozen=True)
class RandomSearch(Strategy):
    num_ants: int = 8

    def default_params(self, problem=None):
        return as_params(RSParams())

    def _init(self, key, problem, params):
        return State(**base_fields(key, params, jnp.zeros_like(problem.lower)))

    def _ask(self, key, state, problem):
        x = jax.random.uniform(key, (self.num_ants, problem.lower.shape[0]),
                               minval=problem.lower, maxval=problem.upper)
        return x * state.params.scale, state

    def scalar_cost(self, fitness):
        return fitness.f

    def _tell(self, state, solutions, fitness, problem):
        return record_best(state, solutions, fitness.f), {}


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


def test_ask_tell_by_hand_equals_minimize():
    """The documented loop (ask -> evaluate -> tell) is what minimize runs."""
    problem, s = _problem(), RandomSearch()
    state = s.init(jax.random.key(2), problem)
    for _ in range(6):
        key, k = jax.random.split(state.key)
        x, state = s.ask(k, state.replace(key=key), problem)
        state, metrics = s.tell(state, x, problem.evaluate(x), problem)
    res = ea.minimize(problem, s, seed=2, iterations=6)
    assert float(state.best_cost) == float(res.best_cost)
    assert set(metrics) >= {"best_cost", "iter_best_cost", "iter_mean_cost"}


def test_stop_rules_end_the_run_and_say_why():
    res = ea.minimize(_problem(), RandomSearch(), seed=1, iterations=200, chunk_size=10,
                      target=0.5)
    assert res.stop_reason == "target" and res.iterations < 200
    assert float(res.best_cost) <= 0.5
    seen = []
    res = ea.minimize(_problem(), RandomSearch(), seed=1, iterations=100, chunk_size=10,
                      callback=lambda state, progress: seen.append(progress.iterations)
                      or progress.iterations >= 30)
    assert seen == [10, 20, 30] and res.iterations == 30 and res.stop_reason == "callback"
    res = ea.minimize(_problem(), RandomSearch(), seed=1, iterations=50, chunk_size=10)
    assert res.stop_reason == "iterations" and res.iterations == 50


def test_second_call_compiles_nothing():
    ea.minimize(_problem(), RandomSearch(num_ants=5), seed=0, iterations=8, chunk_size=4)
    again = ea.minimize(_problem(), RandomSearch(num_ants=5), seed=9, iterations=12,
                        chunk_size=4)
    assert again.compile_seconds == 0.0 and again.iterations == 12
    other = ea.minimize(_problem(), RandomSearch(num_ants=6), seed=0, iterations=8, chunk_size=4)
    assert other.compile_seconds > 0.0  # another static configuration compiles


def test_compile_seconds_count_the_initial_state():
    """The initial state's program is compiled too and counted: with the chunk still
    compiled in this process and the initialiser forgotten, a call reports its compile."""
    from eaco_jax.driver import programs

    ea.minimize(_problem(), RandomSearch(num_ants=7), seed=0, iterations=8, chunk_size=4)
    programs._INITS.clear()
    again = ea.minimize(_problem(), RandomSearch(num_ants=7), seed=0, iterations=8,
                        chunk_size=4)
    assert again.compile_seconds > 0.0


def test_target_uses_full_precision_feasible_objective():
    """At g10's size float32 steps are 5e-4: the target compares float64 best_f."""
    from eaco_jax.driver.stop import Progress, Target

    class S:  # a constrained state: best_cost is float32, best_f float64
        best_cost = np.float32(7049.2481)
        best_f = np.float64(7049.2482)  # 1e-4 above the target; float32 rounds it below
        best_violation = np.float64(0.0)

    p = Progress(1, 0.0, 0.0)
    assert not Target(7049.24802052867 + 1e-4)(S, p)  # float32 would say "reached"
    S.best_f = np.float64(7049.24805)
    assert Target(7049.24802052867 + 1e-4)(S, p)
    S.best_violation = np.float64(1e-3)
    assert not Target(7049.24802052867 + 1e-4)(S, p)  # infeasible never reaches a target


def test_kept_programs_make_room_when_the_process_nears_its_map_limit(monkeypatch):
    """Past half of vm.max_map_count the older half of the kept chunks and initialisers go
    before the next compilation (each XLA:CPU program holds hundreds of memory maps, and a
    process at the limit dies inside XLA); below it, and where /proc says nothing, all stay."""
    from eaco_jax.driver import programs
    from eaco_jax.strategies import GraphEACO

    used, limit = programs.memory_maps()  # this is Linux: the real counts
    assert 0 < used < limit
    tsp = ea.problems.get("burma14")

    def ants_kept(cache):
        return sorted(k[1].num_ants for k in cache)

    monkeypatch.setattr(programs, "memory_maps", lambda: None)
    programs.clear_compiled()
    for ants in (4, 5, 6, 7):
        ea.minimize(tsp, GraphEACO(num_ants=ants), seed=0, iterations=1)
    assert ants_kept(programs._COMPILED) == ants_kept(programs._INITS) == [4, 5, 6, 7]
    calls = []

    def crowded():  # over half the limit once, then (the older programs freed) under it
        calls.append(1)
        return (600, 1000) if len(calls) == 1 else (400, 1000)

    monkeypatch.setattr(programs, "memory_maps", crowded)
    ea.minimize(tsp, GraphEACO(num_ants=8), seed=0, iterations=1)
    assert ants_kept(programs._COMPILED) == ants_kept(programs._INITS) == [6, 7, 8]
    monkeypatch.setattr(programs, "memory_maps", lambda: (500, 1000))  # exactly half: room enough
    ea.minimize(tsp, GraphEACO(num_ants=9), seed=0, iterations=1)
    assert ants_kept(programs._COMPILED) == [6, 7, 8, 9]
    programs.clear_compiled()


@struct.dataclass
class RowSizedSphere(Sphere):
    """A problem whose evaluation holds a buffer per call (as MuJoCo Warp's contacts): the
    driver tells it how many vmapped rows share it; here the count offsets the cost, so the
    result shows whether the driver did."""

    rows: int = struct.field(pytree_node=False, default=1)

    def for_rows(self, rows):
        return self.replace(rows=rows)

    def evaluate(self, x):
        return Evaluation(f=jnp.sum(x**2, axis=-1) + self.rows,
                          violation=jnp.zeros(x.shape[0]))


def test_vmapped_rows_are_announced_to_the_problem():
    """``minimize`` over seeds x settings hands the problem ``for_rows(rows)`` before it
    compiles (the MuJoCo Warp gait problem sizes its shared contact buffer by it)."""
    p = RowSizedSphere(lower=-jnp.ones(3), upper=jnp.ones(3))
    one = ea.minimize(p, RandomSearch(), seed=1, iterations=3)
    three = ea.minimize(p, RandomSearch(), seed=[1, 2, 3], iterations=3)
    assert 1 <= float(one.best_cost) < 1 + 3
    assert np.all(np.asarray(three.best_cost) >= 3)
