"""Compiled programs take a problem without its host-only metadata (driver.programs.device_view):
a new instance of the same shapes and settings reuses them, and results keep the metadata."""

from __future__ import annotations

import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.driver.programs import clear_compiled, device_view, signature
from eaco_jax.problems.tsp import TSP
from eaco_jax.problems.tsp_sparse import SparseTSP
from eaco_jax.strategies.graph_eaco import GraphEACO


def _pair(kind):
    rng = np.random.default_rng(5)
    a, b = (rng.integers(0, 10_000, (80, 2)) for _ in range(2))
    if kind == "sparse":
        return (SparseTSP.from_coords(a, name="first", optimum=1e9, neighbors=8),
                SparseTSP.from_coords(b, name="second", optimum=2e9, neighbors=8))
    return (TSP.from_coords(a, name="first", optimum=1e9),
            TSP.from_coords(b, name="second", optimum=2e9))


@pytest.mark.parametrize("kind", ["sparse", "dense"])
def test_two_instances_of_one_size_share_their_compiled_programs(kind):
    first, second = _pair(kind)
    assert signature(first) != signature(second)  # the metadata differs ...
    assert signature(device_view(first)) == signature(device_view(second))  # ... the view not
    s = GraphEACO(num_ants=4, local_search="2opt", preset="mmas")
    clear_compiled()
    one = ea.minimize(first, s, seed=0, iterations=2)
    two = ea.minimize(second, s, seed=0, iterations=2)
    assert one.compile_seconds > 0 and two.compile_seconds == 0.0
    # the results are the second instance's: its tour, length and gap
    assert two.best_cost == pytest.approx(second.exact_length(two.best_solution))
    assert second.gap(two.best_cost) == pytest.approx(two.best_cost / 2e9 - 1)
    alone = ea.minimize(second, s, seed=0, iterations=2)
    np.testing.assert_array_equal(alone.best_solution, two.best_solution)
