"""Islands: migration moves exactly the right ants; no migration = independent runs, bit for bit;
exact resume; determinism; heterogeneous islands. (Sharded runs: test_islands_sharding.py.)"""

from __future__ import annotations

import dataclasses
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.driver.minimize import run
from eaco_jax.errors import ConfigError
from eaco_jax.problems import functions
from eaco_jax.problems.base import Evaluation
from eaco_jax.problems.tsp import load_tsplib
from eaco_jax.strategies import ContinuousEACO, GraphEACO
from eaco_jax.strategies.base import State, Strategy, base_fields, replacement_slots
from eaco_jax.strategies.islands import Islands, emigrants, migrate, route

INNER = GraphEACO(num_ants=4, local_search="none")


@dataclasses.dataclass(frozen=True)
class Toy(Strategy):
    """Only what migration reads: best-so-far, scalar costs, the default immigrate."""

    num_ants: int = 3


# ants: island c, ant a has solution [10 c + a]; best-so-far solutions and costs by hand
ANT_COST = np.array([[5, 3, 9], [4, 4, 7], [8, 8, 6], [1, 2, 3]], np.float32)
BEST_X = np.array([1, 100, 200, 30], np.float32)  # islands 0 and 3: a copy of an ant
BEST_COST = np.array([3, 2, 0.5, 1], np.float32)
EMIGRANTS = [[1, 0], [100, 10], [200, 22], [30, 31]]  # k = 2, hand-ranked


def _toy_islands():
    c, m = ANT_COST.shape
    xs = (10 * np.arange(c)[:, None] + np.arange(m)[None, :]).astype(np.float32)[..., None]
    fields = base_fields(jax.random.key(0), {}, jnp.zeros(1))
    islands = State(**{k: jnp.stack([jnp.asarray(v)] * c) for k, v in fields.items()
                       if k not in ("key", "params")}, key=jax.random.split(jax.random.key(0), c),
                    params={})
    islands = islands.replace(best_solution=jnp.asarray(BEST_X)[:, None],
                              best_cost=jnp.asarray(BEST_COST))
    return islands, jnp.asarray(xs), jnp.asarray(ANT_COST)


def _ids(x) -> list[list[int]]:
    return np.asarray(x)[..., 0].astype(int).tolist()


def test_emigrants_are_the_best_of_best_so_far_and_ants():
    islands, xs, fs = _toy_islands()
    ex, ef = emigrants(Toy(), islands, xs, fs, 2)
    assert _ids(ex) == EMIGRANTS
    np.testing.assert_array_equal(ef, [[3, 5], [2, 4], [0.5, 6], [1, 2]])


@pytest.mark.parametrize("topology, expected", [
    ("ring", [EMIGRANTS[3], EMIGRANTS[0], EMIGRANTS[1], EMIGRANTS[2]]),
    # all: the two best emigrants of the other islands (ties: lower island first)
    ("all", [[200, 30], [200, 30], [30, 100], [200, 100]]),
])
def test_topologies_route_hand_checked(topology, expected):
    islands, xs, fs = _toy_islands()
    ex, ef = emigrants(Toy(), islands, xs, fs, 2)
    ix, _ = route(topology, ex, ef, ef, jnp.zeros_like(ef), jax.random.key(0))
    assert _ids(ix) == expected


def test_random_topology_takes_all_emigrants_of_one_other_island():
    islands, xs, fs = _toy_islands()
    ex, ef = emigrants(Toy(), islands, xs, fs, 2)
    seen = set()
    for s in range(30):
        ix, ifit = route("random", ex, ef, ef, jnp.zeros_like(ef), jax.random.key(s))
        for j, got in enumerate(_ids(ix)):
            src = EMIGRANTS.index(got)
            assert src != j
            np.testing.assert_array_equal(ifit[j], ef[src])
            seen.add((j, src))
    assert len(seen) == 12  # every other island is drawn for every island
    again, _ = route("random", ex, ef, ef, jnp.zeros_like(ef), jax.random.key(3))
    assert _ids(again) == _ids(route("random", ex, ef, ef, jnp.zeros_like(ef),
                                     jax.random.key(3))[0])


def test_default_immigrate_adopts_a_better_migrant_only():
    islands, xs, fs = _toy_islands()
    islands = islands.replace(stagnation=jnp.full((4,), 7, jnp.int32))
    out = migrate(Islands(Toy(), islands=4, migrants=2), islands, xs, fs, jax.random.key(0))
    # ring: 0 <- 3 (best 1 < 3: adopts 30), 1 <- 0 (3 > 2), 2 <- 1 (2 > .5), 3 <- 2 (.5 < 1)
    assert _ids(out.best_solution) == [30, 100, 200, 200]
    np.testing.assert_array_equal(out.best_cost, [1, 2, 0.5, 0.5])
    np.testing.assert_array_equal(out.stagnation, [0, 7, 7, 0])


def test_replacement_slots():
    assert replacement_slots(jax.random.key(0), 5, 2, "worst").tolist() == [3, 4]
    for s in range(20):
        slots = np.asarray(replacement_slots(jax.random.key(s), 5, 3, "random"))
        assert len(set(slots)) == 3 and slots.min() >= 1 and slots.max() <= 4
    with pytest.raises(ConfigError):
        replacement_slots(jax.random.key(0), 5, 5, "random")


@pytest.fixture(scope="module")
def archive_state():
    strategy = ContinuousEACO(num_ants=2, archive_size=5, refine_ants=0, repair_steps=0,
                              constraint_method="deb")
    problem = functions.sphere(dim=2)
    state = strategy.init(jax.random.key(0), problem)
    x = jnp.arange(10.0, dtype=state.archive_x.dtype).reshape(5, 2)
    f = jnp.arange(1.0, 6.0, dtype=state.archive_f.dtype)
    state = state.replace(archive_x=x, archive_f=f, archive_v=jnp.zeros_like(f), best_f=f[0],
                          best_violation=jnp.zeros_like(f[0]), best_solution=x[0],
                          best_cost=jnp.float32(1), stagnation=jnp.int32(9))
    return strategy, state


def _migrants(dtype, f):
    x = jnp.array([[-1.0, -1.0], [-2.0, -2.0]], dtype)
    return x, Evaluation(f=jnp.asarray(f, dtype), violation=jnp.zeros(2, dtype))


def test_continuous_immigrate_replaces_the_worst_archive_members(archive_state):
    strategy, state = archive_state
    x, fit = _migrants(state.archive_x.dtype, [2.5, 0.5])
    out = strategy.immigrate(state, x, fit, jax.random.key(0), "worst")
    # ranks 3, 4 (f = 4, 5) leave; the archive is re-ranked; 0.5 is the new best
    np.testing.assert_array_equal(out.archive_f, [0.5, 1, 2, 2.5, 3])
    np.testing.assert_array_equal(out.archive_x[0], [-2, -2])
    np.testing.assert_array_equal(out.archive_x[3], [-1, -1])
    assert float(out.best_f) == 0.5 and int(out.stagnation) == 0
    np.testing.assert_array_equal(out.best_solution, [-2, -2])


def test_continuous_immigrate_random_keeps_the_best_and_skips_copies(archive_state):
    strategy, state = archive_state
    x, fit = _migrants(state.archive_x.dtype, [2.5, 7.0])
    key = jax.random.key(4)
    slots = set(np.asarray(replacement_slots(key, 5, 2, "random")).tolist())
    out = strategy.immigrate(state, x, fit, key, "random")
    kept = sorted(set(range(1, 6)) - {int(state.archive_f[s]) for s in slots})
    assert sorted(np.asarray(out.archive_f).tolist()) == sorted(kept + [2.5, 7.0])
    assert float(out.archive_f[0]) == 1.0 and int(out.stagnation) == 9  # no better migrant
    copy = strategy.immigrate(state, state.archive_x[:2], Evaluation(
        f=state.archive_f[:2], violation=jnp.zeros(2, state.archive_f.dtype)), key, "worst")
    np.testing.assert_array_equal(copy.archive_f, state.archive_f)  # no duplicates


def test_graph_immigrate_updates_best_and_restart_best():
    problem = load_tsplib("burma14")
    state = INNER.init(jax.random.key(0), problem)
    state = state.replace(best_cost=jnp.float32(4000), restart_best_cost=jnp.float32(3900),
                          since_improvement=jnp.int32(5))
    tours = jnp.stack([jnp.arange(14), jnp.arange(14)[::-1]]).astype(jnp.int32)
    out = INNER.immigrate(state, tours, jnp.array([3800.0, 3700.0]), jax.random.key(0))
    np.testing.assert_array_equal(out.best_solution, tours[1])
    np.testing.assert_array_equal(out.restart_best_solution, tours[1])
    assert float(out.best_cost) == 3700 and int(out.since_improvement) == 0
    worse = INNER.immigrate(state, tours, jnp.array([4100.0, 4200.0]), jax.random.key(0))
    assert float(worse.best_cost) == 4000 and int(worse.since_improvement) == 5


# --------------------------------------------------------------------------- whole runs
@pytest.fixture(scope="module")
def burma():
    return load_tsplib("burma14")


def _tree_equal(a, b):
    for (path, x), y in zip(jax.tree_util.tree_leaves_with_path(a), jax.tree.leaves(b),
                            strict=True):
        if jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key):
            x, y = jax.random.key_data(x), jax.random.key_data(y)
        np.testing.assert_array_equal(x, y, err_msg=jax.tree_util.keystr(path))


@pytest.mark.parametrize("every", [None, 1000])
def test_no_migration_equals_independent_runs_bit_for_bit(burma, every):
    wrapper = Islands(INNER, islands=3, every=every)
    res = ea.minimize(burma, wrapper, seed=7, iterations=6, chunk_size=3)
    keys = wrapper.island_keys(jax.random.key(7))
    # the C islands' keys as C independent runs of the driver (one vmapped call): bit for bit
    batch = run(INNER, burma, jax.vmap(lambda k: INNER.init(k, burma))(keys), total=6,
                chunk=3, seeds=[0, 1, 2])
    _tree_equal(res.state.islands, batch.state)
    np.testing.assert_array_equal(res.history["island_best_cost"], batch.history["best_cost"].T)
    for i in range(3):  # each island alone: the same tours; the pheromone within float32
        # rounding (XLA fuses a batched update differently: as for vmapped vs looped seeds)
        alone = run(INNER, burma, INNER.init(keys[i], burma), total=6, chunk=3, seeds=[0])
        mine = jax.tree.map(lambda a, i=i: a[i], res.state.islands)
        _tree_equal(mine.replace(tau=alone.state.tau), alone.state)
        np.testing.assert_allclose(mine.tau, alone.state.tau, rtol=1e-6)
    assert int(res.evaluations) == 3 * 4 * 6
    assert float(res.best_cost) == float(np.min(res.history["island_best_cost"][-1]))


def test_migration_changes_the_run(burma):
    base = dict(seed=7, iterations=6, chunk_size=3)
    never = ea.minimize(burma, Islands(INNER, islands=3, every=None), **base)
    often = ea.minimize(burma, Islands(INNER, islands=3, every=1, topology="all"), **base)
    assert int(often.state.migrations) == 6
    assert not np.array_equal(never.history["island_best_cost"],
                              often.history["island_best_cost"])
    # after the last migration every island holds at least the best of the others
    last = often.history["island_best_cost"][-1]
    assert np.all(last <= np.sort(last)[1])


def _hetero(burma):
    """Random topology, per-island beta, two seeds: what the next two tests run (compiled once)."""
    w = Islands(INNER, islands=3, every=2, topology="random")
    params = w.per_island([INNER.default_params(burma).replace(beta=jnp.float32(b))
                           for b in (1.0, 2.0, 3.0)])
    return w, dict(params=[params], iterations=8, chunk_size=2)


def test_deterministic_from_a_seed(burma):
    w, kw = _hetero(burma)
    a, b = (ea.minimize(burma, w, seed=[1, 2], **kw) for _ in range(2))
    c = ea.minimize(burma, w, seed=[3, 2], **kw)
    _tree_equal(a.state, b.state)
    assert not np.array_equal(jax.random.key_data(a.state.islands.key[0]),
                              jax.random.key_data(c.state.islands.key[0]))
    _tree_equal(jax.tree.map(lambda x: x[1], a.state), jax.tree.map(lambda x: x[1], c.state))


def test_resumed_island_run_is_bit_identical(tmp_path, burma):
    w, kw = _hetero(burma)
    unbroken = ea.minimize(burma, w, seed=[1, 2], **kw)
    assert int(unbroken.state.migrations[0]) == 4
    full = tmp_path / "full"
    ea.minimize(burma, w, seed=[1, 2], checkpointing=ea.Checkpointing(full, every=4), **kw)
    part = tmp_path / "part"
    shutil.copytree(full, part)
    shutil.rmtree(part / "8")  # the run died after saving step 4
    resumed = ea.minimize(burma, w, seed=[1, 2], checkpointing=ea.Checkpointing(part, every=4),
                          **kw)
    _tree_equal(unbroken.state, resumed.state)
    assert unbroken.history.keys() == resumed.history.keys()
    for k in unbroken.history:
        np.testing.assert_array_equal(unbroken.history[k], resumed.history[k], err_msg=k)


def test_heterogeneous_params_and_checks(burma):
    w = Islands(INNER, islands=2)
    p = INNER.default_params(burma)
    state = w.init(jax.random.key(0), burma, w.per_island([p, p.replace(q0=jnp.float32(0.9))]))
    np.testing.assert_array_equal(state.islands.params.q0, np.float32([0.0, 0.9]))
    shared = w.init(jax.random.key(0), burma, p.replace(q0=jnp.float32(0.5)))
    np.testing.assert_array_equal(shared.islands.params.q0, [0.5, 0.5])
    with pytest.raises(ConfigError):
        w.per_island([p])
    with pytest.raises(ConfigError):
        Islands(INNER, topology="star")
    with pytest.raises(ConfigError):
        Islands(INNER, migrants=6)  # 4 ants + the best-so-far
    assert w.num_ants == 8 and w.problem_kind == "graph"


def test_float64_continuous_islands_keep_their_dtypes():
    from eaco_jax.problems import float64

    with float64():
        problem = functions.sphere(dim=2)
        inner = ContinuousEACO(num_ants=3, archive_size=4, refine_ants=0, repair_steps=0)
        res = ea.minimize(problem, Islands(inner, islands=2, every=1), seed=0, iterations=2)
    assert res.state.best_f.dtype == np.float64 and res.state.evaluations.dtype == np.int32
    assert int(res.state.migrations) == 2 and np.isfinite(res.f)
    assert float(res.f) == float(np.asarray(res.state.islands.best_f).min())
