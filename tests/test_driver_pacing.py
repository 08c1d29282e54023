"""Paced chunks (``minimize(..., chunk_seconds=)``): each compiled call runs as many of its
iterations as the last call's pace allows, the search itself unchanged."""

from __future__ import annotations

import numpy as np
import pytest

import eaco_jax as ea
from eaco_jax.driver.minimize import paced_length
from eaco_jax.errors import ConfigError


def test_paced_length_follows_the_pace_and_the_time_left():
    assert paced_length(None, 0.2, None) == 1  # no pace yet: one iteration
    assert paced_length(0.01, 0.2, None) == 20
    assert paced_length(0.01, 0.2, 0.05) == 5  # no more than the time rules leave
    assert paced_length(0.5, 0.2, None) == 1  # at least one
    assert paced_length(0.01, 0.2, -1.0) == 1


def _run(chunk_seconds, calls):
    tsp = ea.problems.load_tsplib("eil51", neighbors=10)
    st = ea.strategies.GraphEACO(num_ants=8, local_search="none")
    return ea.minimize(tsp, st, seed=3, iterations=40, chunk_size=16,
                       chunk_seconds=chunk_seconds,
                       callback=lambda state, progress: calls.append(progress.iterations))


def test_pacing_changes_the_chunks_not_the_search():
    plain, tiny, wide = [], [], []
    a = _run(None, plain)
    b = _run(1e-9, tiny)  # a pace no chunk can keep: one iteration per call
    c = _run(60.0, wide)  # the first call runs one iteration, then whole chunks
    assert plain == [16, 32, 40]
    assert tiny == list(range(1, 41))
    assert wide == [1, 17, 33, 40]
    for r in (b, c):
        assert float(r.best_cost) == float(a.best_cost)
        np.testing.assert_array_equal(np.asarray(r.best_solution), np.asarray(a.best_solution))
        np.testing.assert_array_equal(r.history["best_cost"], a.history["best_cost"])


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), True])
def test_a_bad_chunk_seconds_is_one_line(bad):
    tsp = ea.problems.load_tsplib("burma14")
    with pytest.raises(ConfigError, match="chunk_seconds must be a finite number > 0"):
        ea.minimize(tsp, seed=0, iterations=2, chunk_seconds=bad)
