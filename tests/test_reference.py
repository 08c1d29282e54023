"""The tour focused ants change: the best so far, or the last iteration's best (Focused ACO's
source solution; GraphEACO.reference)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from eaco_jax.errors import ConfigError
from eaco_jax.problems.tsp_sparse import SparseTSP
from eaco_jax.strategies.graph_eaco import GraphEACO

N = 150


def _edges(t) -> set[frozenset]:
    return {frozenset((int(a), int(b))) for a, b in zip(t, np.roll(t, -1), strict=True)}


def _problem() -> SparseTSP:
    return SparseTSP.from_coords(np.random.default_rng(7).integers(0, 100_000, (N, 2)),
                                 neighbors=8)


def _colony(reference: str, prob: float = 0.0) -> GraphEACO:
    # one 2-opt move per ant and no search: each ant is its reference but two edges
    return GraphEACO(num_ants=8, local_search="none", preset="mmas", construction="moves",
                     max_new_edges=1, seed_tour=False, reference=reference,
                     reference_best_prob=prob)


def _new_edges(tours, ref) -> list[int]:
    return [len(_edges(t) - _edges(ref)) for t in np.asarray(tours)]


def test_iteration_reference_changes_the_last_iterations_best_not_the_best_so_far():
    p = _problem()
    rng = np.random.default_rng(1)
    best = rng.permutation(N).astype(np.int32)
    source = rng.permutation(N).astype(np.int32)
    for reference, prob, ref in (("iteration", 0.0, source), ("iteration", 1.0, best),
                                 ("best", 0.0, best)):
        s = _colony(reference, prob)
        state = s.init(jax.random.key(0), p)
        state = state.replace(best_solution=best, best_cost=np.float32(1.0), source=source)
        tours, _ = s.ask(jax.random.key(2), state, p)
        assert _new_edges(tours, ref) == [2] * 8, (reference, prob)


def test_tell_keeps_the_iterations_best_tour_as_the_next_source():
    p = _problem()
    s = _colony("iteration")
    state = s.init(jax.random.key(0), p)
    np.testing.assert_array_equal(state.source, state.first_tour)
    tours, state = s.ask(jax.random.key(1), state, p)
    lengths = np.asarray(p.evaluate(tours))
    # the best so far is better than the whole iteration: the source is the iteration's best
    state = state.replace(best_cost=np.float32(lengths.min() / 2))
    state, _ = s.tell(state, tours, lengths, p)
    np.testing.assert_array_equal(state.source, np.asarray(tours)[np.argmin(lengths)])
    assert not np.array_equal(state.source, state.best_solution)


def test_a_run_with_the_iteration_reference_is_reproducible():
    import eaco_jax as ea

    p = _problem()
    s = GraphEACO(num_ants=6, local_search="2opt", preset="mmas", construction="moves-new",
                  max_new_edges=4, ls_focus_width=16, reference="iteration",
                  reference_best_prob=0.3)
    full = ea.minimize(p, s, seed=3, iterations=6)
    assert sorted(np.asarray(full.best_solution).tolist()) == list(range(N))
    again = ea.minimize(p, s, seed=3, iterations=6)
    np.testing.assert_array_equal(full.best_solution, again.best_solution)


def test_bad_reference_settings_are_refused():
    with pytest.raises(ConfigError, match="reference='worst' is not one of"):
        GraphEACO(reference="worst")
    with pytest.raises(ConfigError, match=r"reference_best_prob must be in \[0, 1\]"):
        GraphEACO(reference="iteration", reference_best_prob=1.5)
