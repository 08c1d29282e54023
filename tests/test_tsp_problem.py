"""The TSP problem pytree: constructors, evaluation, neighbour lists, helpers."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.problems import TSP, load_tsplib
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp import (
    DATA_DIR,
    bundled_instances,
    nearest_neighbour_tour,
    tour_length,
    validate_tour,
)


def test_load_bundled_and_evaluate_matches_exact_length():
    p = load_tsplib("eil51", neighbors=10)
    assert p.kind == "graph" and p.name == "eil51" and p.optimum == 426 and p.n == 51
    assert p.dist.dtype == jnp.float32 and p.neighbors.shape == (51, 10)
    rng = np.random.default_rng(0)
    tours = np.stack([rng.permutation(51) for _ in range(4)]).astype(np.int32)
    got = np.asarray(p.evaluate(tours))  # from the host: checked tours, exact float64
    want = [tour_length(np.asarray(p.dist), t) for t in tours]
    assert got.dtype == np.float64 and got.shape == (4,)
    np.testing.assert_array_equal(got, want)
    # jit with the problem as an argument (pytree) and vmap over a batch of batches
    f = jax.jit(lambda prob, t: prob.evaluate(t))
    np.testing.assert_array_equal(f(p, tours), got)
    np.testing.assert_array_equal(jax.vmap(p.evaluate)(tours[None]), got[None])


def test_load_by_path_and_unknown_name(tmp_path):
    p = load_tsplib(str(DATA_DIR / "burma14.tsp"))
    assert p.name == "burma14" and p.optimum == 3323 and p.neighbors.shape == (14, 13)
    with pytest.raises(ProblemError, match="bundled: .*eil51"):
        load_tsplib("eil5")
    custom = tmp_path / "tri.tsp"
    custom.write_text(
        "NAME : tri\nDIMENSION : 3\nEDGE_WEIGHT_TYPE : EUC_2D\n"
        "NODE_COORD_SECTION\n1 0 0\n2 3 0\n3 0 4\nEOF\n"
    )
    q = load_tsplib(custom)
    assert q.optimum is None and float(q.evaluate(jnp.array([[0, 1, 2]]))[0]) == 12
    assert set(bundled_instances()) >= {"burma14", "ulysses22", "att48", "a280", "pcb442"}


def test_neighbors_are_sorted_nearest_without_self():
    p = load_tsplib("berlin52", neighbors=8)
    d = np.asarray(p.dist)
    nb = np.asarray(p.neighbors)
    assert not np.any(nb == np.arange(52)[:, None])
    rows = d[np.arange(52)[:, None], nb]
    assert np.all(np.diff(rows, axis=1) >= 0)
    dd = d + np.diag(np.full(52, np.inf))
    np.testing.assert_array_equal(rows[:, -1], np.sort(dd, axis=1)[:, 7])


def test_from_coords_and_metric_validation():
    xy = np.array([[0, 0], [3, 4], [6, 8], [0, 8]], float)
    p = TSP.from_coords(xy, name="sq", neighbors=50)
    assert p.neighbors.shape == (4, 3) and float(p.dist[0, 1]) == 5.0 and p.integer
    q = TSP.from_coords(xy + [[0.0, 0.25], [0, 0], [0, 0], [0, 0]])
    assert not q.integer and float(q.dist[0, 1]) == np.float32(np.hypot(3.0, 3.75))
    with pytest.raises(ProblemError, match="metric"):
        TSP.from_coords(xy, metric="MAN_2D")
    with pytest.raises(ProblemError, match=r"shape \(n, 2\)"):
        TSP.from_coords(np.zeros((4, 3)))
    with pytest.raises(ProblemError, match="NaN"):
        TSP.from_coords(np.array([[0, 0], [1, np.nan], [2, 2]]))


@pytest.mark.parametrize(
    "d, match",
    [
        (np.zeros((3, 4)), "square"),
        (np.array([[0, 1, 2], [1, 0, 3], [2, 3, np.nan]]), "NaN"),
        (np.array([[0, -1, 2], [-1, 0, 3], [2, 3, 0]]), "negative"),
        (np.array([[0, 1, 2], [5, 0, 3], [2, 3, 0]]), "symmetric"),
        (np.array([[1, 1, 2], [1, 0, 3], [2, 3, 0]]), "diagonal"),
        (np.zeros((2, 2)), "at least 3"),
    ],
)
def test_from_distance_matrix_validation(d, match):
    with pytest.raises(ProblemError, match=match):
        TSP.from_distance_matrix(d)


def test_nearest_neighbour_tour_is_greedy_permutation():
    p = load_tsplib("att48")
    d = np.asarray(p.dist)
    t = nearest_neighbour_tour(d, start=5)
    validate_tour(t, 48)
    assert t[0] == 5
    visited = {int(t[0])}
    for i in range(1, 48):  # each step goes to the nearest unvisited city
        rest = [c for c in range(48) if c not in visited]
        assert d[t[i - 1], t[i]] == min(d[t[i - 1], c] for c in rest)
        visited.add(int(t[i]))
    assert tour_length(d, t) >= p.optimum
    with pytest.raises(ProblemError, match="start"):
        nearest_neighbour_tour(d, start=48)


def test_validate_tour_errors():
    with pytest.raises(ProblemError, match="shape"):
        validate_tour(np.arange(4), 5)
    with pytest.raises(ProblemError, match="permutation"):
        validate_tour(np.array([0, 1, 1, 3]), 4)
    with pytest.raises(ProblemError, match="outside"):
        validate_tour(np.array([0, 1, 2, 4]), 4)
    assert validate_tour(np.array([3, 1, 2, 0]), 4).dtype == np.int64
