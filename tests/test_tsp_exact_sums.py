"""Tour lengths past 2**31 stay exact: two int32 words inside a run, int64 on the host."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.problems import TSP
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp import WIDE_SUM_MAX_CITIES, exact_int_sum, words_needed
from eaco_jax.strategies.graph_eaco import GraphEACO


def _long_matrix(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = np.triu(rng.integers(10_000_000, 2**24, (n, n)), 1)
    return d + d.T


def test_tours_past_2_31_are_exact_inside_and_outside_a_run():
    n = 200
    d = _long_matrix(n, 0)
    p = TSP.from_distance_matrix(d)
    assert p.integer and p.sum_words == 2
    rng = np.random.default_rng(1)
    tours = np.stack([rng.permutation(n) for _ in range(64)]).astype(np.int32)
    exact = np.array([d[t, np.roll(t, -1)].sum() for t in tours], np.int64)
    assert exact.min() > 2**31
    np.testing.assert_array_equal(p.evaluate(tours), exact)  # host: int64
    traced = np.asarray(jax.jit(lambda q, t: q.evaluate(t))(p, tours))
    np.testing.assert_array_equal(traced, exact.astype(np.float32))  # exact, rounded once
    res = ea.minimize(p, GraphEACO(num_ants=4, local_search="2opt"), seed=0, iterations=2)
    t = np.asarray(res.best_solution)
    assert res.best_cost == d[t, np.roll(t, -1)].sum()


def test_wide_sum_is_exact_and_monotone():
    rng = np.random.default_rng(2)
    edges = rng.integers(0, 2**24, (256, 5000)).astype(np.int32)
    exact = edges.astype(np.int64).sum(1)
    got = np.asarray(exact_int_sum(edges))
    np.testing.assert_array_equal(got, exact.astype(np.float32))
    # past 2**36 the float32 rounding stays monotone: a shorter tour never compares longer
    big = np.full((2, 6000), 2**24 - 1, np.int32)
    big[1, 0] -= 1
    lo, hi = np.asarray(exact_int_sum(big[::-1]))
    assert lo <= hi


def test_small_instances_keep_one_word_and_large_counts_are_refused():
    assert words_needed(2**31 - 1, 10) == 1 and words_needed(2**31, 10) == 2
    with pytest.raises(ProblemError, match="two int32 words"):
        words_needed(2.0**40, WIDE_SUM_MAX_CITIES + 1)
    xy = np.random.default_rng(3).integers(0, 10_000_000, (300, 2))
    p = TSP.from_coords(xy, metric="EUC_2D")  # refused before: tours could reach 2**31
    assert p.sum_words == 2
