"""Multi-objective mode: Pareto ops against brute force, the test problems' fronts, MOEACO."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.ops import pareto
from eaco_jax.problems.multiobjective import MultiObjectiveProblem, zdt1, zdt3
from eaco_jax.strategies.mo_eaco import MOEACO


# --------------------------------------------------------------------------- brute force
def brute_dominates(fa, va, fb, vb) -> bool:
    if va <= 0 and vb > 0:
        return True
    if va > 0 and vb > 0:
        return va < vb
    if va > 0:
        return False
    return bool(np.all(fa <= fb) and np.any(fa < fb))


def brute_rank(f, v) -> np.ndarray:
    n = len(f)
    rank = np.full(n, -1)
    r = 0
    while np.any(rank < 0):
        left = np.flatnonzero(rank < 0)
        front = [j for j in left
                 if not any(brute_dominates(f[i], v[i], f[j], v[j]) for i in left)]
        rank[front] = r
        r += 1
    return rank


def brute_crowding(f, rank) -> np.ndarray:
    n, m = f.shape
    d = np.zeros(n)
    for r in np.unique(rank):
        idx = np.flatnonzero(rank == r)
        for j in range(m):
            o = idx[np.argsort(f[idx, j], kind="stable")]
            span = f[o[-1], j] - f[o[0], j]
            d[o[0]] = d[o[-1]] = np.inf
            for a in range(1, len(o) - 1):
                if span > 0:
                    d[o[a]] += (f[o[a + 1], j] - f[o[a - 1], j]) / span
    return d


def brute_hypervolume(f, ref) -> float:
    """Union volume over the grid of all coordinates: a cell counts if a point is <= its
    lower corner in every objective."""
    f = f[np.all(f < ref, axis=1)]
    if len(f) == 0:
        return 0.0
    axes = [np.unique(np.concatenate([f[:, j], [ref[j]]])) for j in range(f.shape[1])]
    vol = 0.0
    for cell in itertools.product(*[range(len(a) - 1) for a in axes]):
        lo = np.array([axes[j][c] for j, c in enumerate(cell)])
        if np.any(np.all(f <= lo, axis=1)):
            vol += np.prod([axes[j][c + 1] - axes[j][c] for j, c in enumerate(cell)])
    return float(vol)


def random_set(seed: int, n: int, m: int, infeasible: bool = True):
    rng = np.random.default_rng(seed)
    f = np.round(rng.random((n, m)) * 4) / 4 if seed % 2 else rng.random((n, m))  # ties
    v = np.where(rng.random(n) < 0.3, np.round(rng.random(n) * 3), 0.0) if infeasible \
        else np.zeros(n)
    return f.astype(np.float32), v.astype(np.float32)


# --------------------------------------------------------------------------- ops
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [2, 3])
def test_rank_matches_brute_force(seed: int, m: int) -> None:
    f, v = random_set(seed, 25, m)
    rank = np.asarray(pareto.nondominated_rank(jnp.asarray(f), jnp.asarray(v)))
    np.testing.assert_array_equal(rank, brute_rank(f, v))


def test_rank_hand_example() -> None:
    # (1,3) (2,2) (3,1) front 0; (2,3) front 1; (3,3) front 2; infeasible ranked by violation
    f = jnp.array([[3, 3], [2, 3], [1, 3], [2, 2], [3, 1], [0, 0], [0, 0]], jnp.float32)
    v = jnp.array([0, 0, 0, 0, 0, 2.0, 1.0], jnp.float32)
    np.testing.assert_array_equal(pareto.nondominated_rank(f, v), [2, 1, 0, 0, 0, 4, 3])


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("m", [2, 3])
def test_crowding_matches_brute_force(seed: int, m: int) -> None:
    f, v = random_set(seed + 10, 30, m, infeasible=False)
    # distinct values: the sort order is unambiguous
    f = (f + np.arange(30)[:, None] * 1e-4).astype(np.float32)
    rank = brute_rank(f, v)
    got = np.asarray(pareto.crowding_distance(jnp.asarray(f), jnp.asarray(rank, jnp.int32)))
    np.testing.assert_allclose(got, brute_crowding(f.astype(np.float64), rank), rtol=1e-5)


def test_order_puts_front_then_isolated_first() -> None:
    f = jnp.array([[0.0, 1.0], [0.1, 0.9], [0.5, 0.5], [1.0, 0.0], [2.0, 2.0]], jnp.float32)
    order, rank, crowd = pareto.rank_crowding_order(f, jnp.zeros(5))
    order = np.asarray(order)
    assert set(order[:2]) == {0, 3}  # extremes (inf crowding)
    assert order[2] == 2 and order[3] == 1 and order[4] == 4  # (0.5, 0.5) is more isolated


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [2, 3])
def test_hypervolume_matches_brute_force(seed: int, m: int) -> None:
    f, _ = random_set(seed + 20, 9, m)
    ref = np.full(m, 0.9, np.float32)
    got = float(pareto.hypervolume(jnp.asarray(f), jnp.asarray(ref)))
    assert got == pytest.approx(brute_hypervolume(f.astype(np.float64), ref), rel=1e-5, abs=1e-7)


def test_hypervolume_hand_examples_and_mask() -> None:
    f2 = jnp.array([[1.0, 3.0], [2.0, 2.0], [3.0, 1.0], [3.5, 3.5]])
    # staircase under (4, 4): 3*1 + 2*1 + 1*1 = 6 (the dominated (3.5, 3.5) adds nothing)
    assert float(pareto.hypervolume(f2, jnp.array([4.0, 4.0]))) == pytest.approx(6.0)
    mask = jnp.array([True, False, True, True])
    # without (2, 2): 3*1 + 1*2 = 5 ... (1,3): [1,4]x[3,4]=3, (3,1): [3,4]x[1,4]=3, overlap 1
    assert float(pareto.hypervolume(f2, jnp.array([4.0, 4.0]), mask)) == pytest.approx(5.0)
    f3 = jnp.array([[0.0, 0.0, 1.0], [1.0, 1.0, 0.0]])
    # (0,0,1): 2*2*1 = 4; (1,1,0): 1*1*2 = 2; overlap 1*1*1 = 1
    assert float(pareto.hypervolume(f3, jnp.array([2.0, 2.0, 2.0]))) == pytest.approx(5.0)


def test_igd_hand_example() -> None:
    ref = jnp.array([[0.0, 1.0], [1.0, 0.0]])
    f = jnp.array([[0.0, 2.0], [1.0, 0.0], [9.0, 9.0]])
    assert float(pareto.igd(f, ref, jnp.array([True, True, False]))) == pytest.approx(0.5)


# --------------------------------------------------------------------------- problems
def test_zdt1_front_and_registry() -> None:
    p = ea.problems.get("zdt1", dim=30)
    x = np.zeros((5, 30), np.float32)
    x[:, 0] = np.linspace(0, 1, 5)
    e = p.evaluate(jnp.asarray(x))
    np.testing.assert_allclose(e.f[:, 1], 1 - np.sqrt(x[:, 0]), atol=1e-6)
    fr = jnp.asarray(p.true_front(4001), jnp.float32)
    assert float(pareto.hypervolume(fr, p.ref_point)) == pytest.approx(p.hv_star, abs=2e-4)
    assert float(pareto.hypervolume(e.f, p.ref_point)) < p.hv_star


def test_dtlz2_front_is_the_unit_sphere() -> None:
    p = ea.problems.get("dtlz2", dim=12)
    x = np.random.default_rng(0).random((50, 12)).astype(np.float32)
    x[:, 2:] = 0.5
    x[:5, :2] = 1.0  # at the bounds: cos(pi/2) must be 0, not -4e-8
    f = np.asarray(p.evaluate(jnp.asarray(x)).f)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 1.0, rtol=1e-5)
    assert np.all(f >= 0)
    x[:5, 2:] = 0.9  # g > 0 at the same angles: dominated by the g = 0 points
    g = np.asarray(p.evaluate(jnp.asarray(x)).f)
    assert np.all(np.all(f[:5] <= g[:5], axis=1) & np.any(f[:5] < g[:5], axis=1))
    fr = jnp.asarray(p.true_front(2000), jnp.float32)
    assert np.allclose(np.linalg.norm(fr, axis=1), 1.0, atol=1e-6)
    assert float(pareto.hypervolume(fr, p.ref_point)) < p.hv_star


def test_zdt3_front_is_nondominated() -> None:
    fr = zdt3().true_front(500)
    rank = brute_rank(fr, np.zeros(len(fr)))
    assert np.all(rank == 0) and len(fr) < 500


def test_bad_problem_is_one_line() -> None:
    with pytest.raises(ea.ProblemError, match="ref_point must be 2 finite numbers"):
        MultiObjectiveProblem(lambda x: x[:2], lower=[0, 0, 0], upper=[1, 1, 1],
                              ref_point=[1.0])
    with pytest.raises(ea.ProblemError, match="k >= 2"):
        MultiObjectiveProblem(lambda x: x[0], lower=[0, 0], upper=[1, 1], ref_point=[1.0])


# --------------------------------------------------------------------------- the colony
def ask_tell(strategy, problem, key, iterations):
    state = strategy.init(key, problem)
    hv = []
    for i in range(iterations):
        x, state = strategy.ask(jax.random.fold_in(key, i), state, problem)
        state, metrics = strategy.tell(state, x, problem.evaluate(x), problem)
        hv.append(float(metrics["hypervolume"]))
    return state, hv


def test_colony_improves_hypervolume_on_zdt1() -> None:
    problem = zdt1(30)
    strategy = MOEACO(num_ants=50, archive_size=50)
    state, hv = ask_tell(strategy, problem, jax.random.key(0), 40)
    # the first tell ranks the random colony: that is the random initial archive's hypervolume
    assert hv[0] < 0.3
    assert hv[-1] > hv[0] + 0.3
    assert all(b >= a - 1e-3 for a, b in zip(hv, hv[1:], strict=False))  # elitist archive
    front = MOEACO.front(state)
    assert np.all(np.diff(front["f"][:, 0]) >= 0) and np.all(front["violation"] <= 0)
    assert float(pareto.hypervolume(jnp.asarray(front["f"]), problem.ref_point)) == \
        pytest.approx(hv[-1], rel=1e-5)
    assert state.evaluations == 40 * 50


def test_vmapped_seeds_through_minimize() -> None:
    problem = zdt1(10)
    strategy = MOEACO(num_ants=20, archive_size=20)
    result = ea.minimize(problem, strategy=strategy, seed=[0, 1, 2], iterations=15)
    hv = result.history["hypervolume"]
    assert hv.shape == (3, 15)
    assert np.all(hv[:, -1] > hv[:, 0] + 0.1)
    assert len({round(float(h), 6) for h in hv[:, -1]}) == 3  # the seeds differ
    np.testing.assert_allclose(-result.best_cost, hv.max(axis=1), rtol=1e-6)
    row = jax.tree.map(lambda a: a[1], result.state)
    front = MOEACO.front(row)
    assert float(pareto.hypervolume(jnp.asarray(front["f"]), problem.ref_point)) == \
        pytest.approx(hv[1, -1], rel=1e-5)
    np.testing.assert_array_equal(result.evaluations, [300, 300, 300])


def test_constrained_front_stays_feasible() -> None:
    # ZDT1 with f1 >= 0.5 (x1 >= 0.5): the front is f2 = 1 - sqrt(f1) for f1 in [0.5, 1]
    base = zdt1(10)
    problem = MultiObjectiveProblem(base.objectives, lambda x: jnp.array([0.5 - x[0]]),
                                    lower=base.lower, upper=base.upper,
                                    ref_point=base.ref_point, name="zdt1-c")
    strategy = MOEACO(num_ants=40, archive_size=40)
    state, hv = ask_tell(strategy, problem, jax.random.key(3), 40)
    front = MOEACO.front(state)
    assert len(front["f"]) >= 10
    assert np.all(front["f"][:, 0] >= 0.5)
    rank0 = np.asarray(state.archive_rank) == 0
    assert np.all(np.asarray(state.archive_v)[rank0] <= 0)  # no infeasible point on front 0
    # the constrained optimum's hypervolume is 0.1*1.1 + integral_0.5^1 (0.1 + sqrt t) dt
    best = 0.11 + 0.05 + (2 / 3) * (1 - 0.5**1.5)
    assert 0.8 * best < hv[-1] <= best + 1e-3


def test_minimize_picks_the_multiobjective_colony() -> None:
    from eaco_jax.driver.minimize import default_strategy

    assert isinstance(default_strategy(zdt1(5)), MOEACO)


def test_wrong_inputs_are_one_line() -> None:
    problem = zdt1(5)
    strategy = MOEACO(num_ants=4, archive_size=4)
    state = strategy.init(jax.random.key(0), problem)
    x, state = strategy.ask(jax.random.key(1), state, problem)
    e = problem.evaluate(x)
    with pytest.raises(ea.ConfigError, match="f of shape"):
        strategy.tell(state, x, e.f, problem)
    with pytest.raises(ea.ConfigError, match="f of shape"):  # one objective per ant
        strategy.tell(state, x, ea.Evaluation(f=e.f[:, 0], violation=e.violation), problem)
    with pytest.raises(ea.ProblemError, match="solves 'continuous' problems"):
        ea.minimize(problem, strategy=ea.strategies.get("continuous-eaco-df"), iterations=2)
    with pytest.raises(ea.ProblemError, match="multi-objective problem"):
        strategy.init(jax.random.key(0), ea.problems.get("sphere", dim=3))
