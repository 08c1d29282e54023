"""two_opt's public counters and acceptance switch, which the local-search benchmarks read:
``return_steps`` (improvement steps per tour) and ``acceptance`` (rounds or one by one)."""

from __future__ import annotations

import numpy as np
import pytest

from eaco_jax.errors import ConfigError
from eaco_jax.ops.local_search import ACCEPTANCES, two_opt
from eaco_jax.problems import load_tsplib


@pytest.fixture(scope="module")
def eil51():
    return load_tsplib("eil51", neighbors=10)


def _tours(n: int, m: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32)


def test_steps_count_the_loop_one_move_per_step(eil51):
    """With one move per step, a search that ends at a local optimum runs one step per move
    and one more that finds nothing; a capped search stops on its last move."""
    tours = _tours(51, 5)
    out, moves, steps = two_opt(tours, eil51.dist, eil51.neighbors, moves_per_step=1,
                                return_steps=True)
    same, same_moves = two_opt(tours, eil51.dist, eil51.neighbors, moves_per_step=1,
                               return_moves=True)
    np.testing.assert_array_equal(np.asarray(out), np.asarray(same))
    np.testing.assert_array_equal(np.asarray(moves), np.asarray(same_moves))
    assert np.all(np.asarray(moves) > 3)
    np.testing.assert_array_equal(np.asarray(steps), np.asarray(moves) + 1)
    _, moves, steps = two_opt(tours, eil51.dist, eil51.neighbors, max_moves=3,
                              moves_per_step=1, return_steps=True)
    np.testing.assert_array_equal(np.asarray(moves), 3)
    np.testing.assert_array_equal(np.asarray(steps), 3)


def test_batched_steps_are_fewer_than_moves(eil51):
    """Several disjoint moves per step: fewer steps than moves, and at least moves / batch."""
    tours = _tours(51, 5, seed=1)
    _, moves, steps = two_opt(tours, eil51.dist, eil51.neighbors, moves_per_step=8,
                              or_opt=True, return_steps=True)
    moves, steps = np.asarray(moves), np.asarray(steps)
    assert np.all(steps < moves)
    assert np.all(steps >= np.ceil(moves / 8))


@pytest.mark.parametrize("or_opt", [False, True])
def test_sequential_acceptance_returns_the_same_tours(eil51, or_opt):
    """The one-by-one greedy and the parallel rounds accept the same moves: same tours,
    same moves, same steps."""
    tours = _tours(51, 6, seed=2)
    got = {a: two_opt(tours, eil51.dist, eil51.neighbors, moves_per_step=16, or_opt=or_opt,
                      return_steps=True, acceptance=a) for a in ACCEPTANCES}
    assert set(got) == {"rounds", "unrolled", "sequential"}
    for other in ("unrolled", "sequential"):
        for a, b in zip(got["rounds"], got[other], strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert np.all(np.asarray(got["rounds"][1]) > 0)


def test_unknown_acceptance_is_a_config_error(eil51):
    with pytest.raises(ConfigError, match="acceptance='greedy' is not one of"):
        two_opt(_tours(51, 1), eil51.dist, acceptance="greedy")
