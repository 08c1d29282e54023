"""Focused construction as 2-opt moves on the reference tour (ops/construction_moves.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.errors import ConfigError
from eaco_jax.ops.construction_moves import construct_tours_moves
from eaco_jax.problems.tsp_sparse import SparseTSP
from eaco_jax.strategies.graph_eaco import GraphEACO

N, K, M = 60, 6, 12


def _setup(seed: int = 0):
    rng = np.random.default_rng(seed)
    p = SparseTSP.from_coords(rng.integers(0, 10_000, (N, 2)), neighbors=K)
    ref = rng.permutation(N).astype(np.int32)
    cand_w = rng.uniform(0.1, 1.0, (N, K)).astype(np.float32)
    return p, ref, cand_w


def _edges(t) -> set[frozenset]:
    return {frozenset((int(a), int(b))) for a, b in zip(t, np.roll(t, -1), strict=True)}


KINDS = [("2opt", True), ("2opt", False), ("or3opt", True), ("or3opt", False)]
NEW = {"2opt": 2, "or3opt": 3}  # new edges of one move


def _build(ref, cand_w, cands, n_moves, walk=True, key=0, q0=0.0, **kw):
    return np.asarray(construct_tours_moves(jax.random.key(key), jnp.asarray(cand_w),
                                            jnp.asarray(cands), jnp.asarray(ref), n_moves, M,
                                            q0, walk=walk, **kw))


@pytest.mark.parametrize(("kind", "walk"), KINDS)
def test_tours_are_permutations_within_two_or_three_edges_per_move_of_the_reference(kind,
                                                                                     walk):
    p, ref, cand_w = _setup()
    factor = np.random.default_rng(3).uniform(0.9, 1.1, (M, N)).astype(np.float32)
    for n_moves in (2, 10):
        tours = _build(ref, cand_w, p.neighbors, n_moves, walk, factor=jnp.asarray(factor),
                       kind=kind)
        assert tours.shape == (M, N) and tours.dtype == np.int32
        changed = []
        for t in tours:
            assert sorted(t) == list(range(N))
            new = len(_edges(t) - _edges(ref))
            assert new <= NEW[kind] * n_moves
            changed.append(new)
        assert max(changed) > 0  # the moves do change tours
    np.testing.assert_array_equal(_build(ref, cand_w, p.neighbors, 0, walk, kind=kind),
                                  np.broadcast_to(ref, (M, N)))


@pytest.mark.parametrize(("kind", "walk"), KINDS)
def test_each_move_inserts_a_candidate_edge_and_its_closing_edges(kind, walk):
    """Move t+1 of an ant (the tours after t and t + 1 moves: the draws of the first t
    moves do not depend on n_moves) removes two (2opt) or three (or3opt) edges and adds
    (c, v), v one of c's candidates, and the closing edges."""
    p, ref, cand_w = _setup(1)
    cands = np.asarray(p.neighbors)
    applied = 0
    before = _build(ref, cand_w, cands, 0, walk, kind=kind)
    for n_moves in range(1, 5):
        after = _build(ref, cand_w, cands, n_moves, walk, kind=kind)
        for a, b in zip(before, after, strict=True):
            added, removed = _edges(b) - _edges(a), _edges(a) - _edges(b)
            assert len(added) == len(removed) in (0, NEW[kind])
            if added:
                applied += 1
                assert any(y in cands[x] for e in added for x, y in (tuple(e), tuple(e)[::-1]))
        before = after
    assert applied > 20


@pytest.mark.parametrize(("kind", "walk"), KINDS)
def test_same_key_same_tours_other_key_other_tours(kind, walk):
    p, ref, cand_w = _setup(2)
    a = _build(ref, cand_w, p.neighbors, 5, walk, key=4, kind=kind)
    np.testing.assert_array_equal(a, _build(ref, cand_w, p.neighbors, 5, walk, key=4,
                                            kind=kind))
    assert not np.array_equal(a, _build(ref, cand_w, p.neighbors, 5, walk, key=5, kind=kind))
    assert len({tuple(t) for t in a}) > 1  # ants draw apart


@pytest.mark.parametrize(("kind", "walk"), KINDS)
def test_greedy_limit_inserts_the_predicted_edge(kind, walk):
    """One nonzero weight per row, or q0 = 1: the move from c inserts (c, its best candidate)."""
    p, ref, cand_w = _setup(3)
    cands = np.asarray(p.neighbors)
    rng = np.random.default_rng(5)
    col = rng.integers(0, K, N)
    one_hot = np.zeros((N, K), np.float32)
    one_hot[np.arange(N), col] = 1.0
    best = cand_w.argmax(axis=1)
    for w, q0, pick in ((one_hot, 0.0, col), (cand_w, 1.0, best)):
        tours = _build(ref, w, cands, 1, walk, q0=q0, kind=kind)
        hits = 0
        for t in tours:
            added = _edges(t) - _edges(ref)
            if added:
                hits += 1
                assert any(y == cands[x, pick[x]] for e in added
                           for x, y in (tuple(e), tuple(e)[::-1]))
        assert hits > M // 2


@pytest.mark.parametrize(("kind", "walk"), KINDS)
def test_every_move_changes_the_tour_unless_told_to_keep_neighbour_draws(kind, walk):
    """skip_neighbours (default): v is never c's tour neighbour, so one move always adds its
    edges; without it a draw of a neighbour (likely: its weight is the largest here) is a
    no-op."""
    _, ref, cand_w = _setup(5)
    rng = np.random.default_rng(6)
    succ, pred = np.empty(N, np.int32), np.empty(N, np.int32)
    succ[ref], pred[ref] = np.roll(ref, -1), np.roll(ref, 1)
    others = [rng.choice(np.setdiff1d(np.arange(N), [c, succ[c], pred[c]]), K - 2,
                         replace=False) for c in range(N)]
    cands = np.column_stack([succ, pred, np.array(others)]).astype(np.int32)
    heavy = cand_w.copy()
    heavy[:, :2] = 1000.0  # the tour neighbours: nearly every draw without skipping
    skip = _build(ref, heavy, cands, 1, walk, kind=kind)
    keep = _build(ref, heavy, cands, 1, walk, skip_neighbours=False, kind=kind)
    assert [len(_edges(t) - _edges(ref)) for t in skip] == [NEW[kind]] * M
    assert sum(len(_edges(t) - _edges(ref)) == 0 for t in keep) > M // 2


@pytest.mark.parametrize("kind", ["2opt", "or3opt"])
def test_walk_chains_the_moves(kind):
    """walk=True: the second move starts at the first move's v and keeps the edge (c, v)."""
    p, ref, cand_w = _setup(4)
    chained = 0
    for a, b in zip(_build(ref, cand_w, p.neighbors, 1, kind=kind),
                    _build(ref, cand_w, p.neighbors, 2, kind=kind), strict=True):
        first, second = _edges(a) - _edges(ref), _edges(b) - _edges(a)
        if first and second:
            # the second move is at a city of a first-move edge (v of (c, v)), which stays
            assert any(e in _edges(b) and e & set().union(*second) for e in first)
            chained += 1
    assert chained > M // 3


def test_strategy_moves_runs_on_the_sparse_path_and_is_refused_on_the_dense_one():
    import eaco_jax as ea
    from eaco_jax.problems import load_tsplib

    rng = np.random.default_rng(7)
    p = SparseTSP.from_coords(rng.integers(0, 100_000, (150, 2)), neighbors=8)
    s = GraphEACO(num_ants=6, local_search="2opt+oropt", preset="mmas", construction="moves",
                  max_new_edges=4)
    res = ea.minimize(p, s, seed=0, iterations=3)
    assert sorted(np.asarray(res.best_solution).tolist()) == list(range(150))
    # one move per ant, nothing after it: each ant's tour is the first tour but 2 or 3 edges
    for construction, new in (("moves", 2), ("moves-or3opt", 3)):
        one = GraphEACO(num_ants=6, local_search="none", preset="mmas",
                        construction=construction, max_new_edges=1, seed_tour=False)
        state = one.init(jax.random.key(1), p)
        tours, _ = one.ask(jax.random.key(2), state, p)
        first = _edges(np.asarray(state.first_tour))
        assert [len(_edges(t) - first) for t in np.asarray(tours)] == [new] * 6
    with pytest.raises(ConfigError, match="construction='moves' needs the sparse path.*"
                       "--sparse on"):
        ea.minimize(load_tsplib("eil51"), s, seed=0, iterations=1)
    with pytest.raises(ConfigError, match="--max-new-edges N"):
        GraphEACO(construction="moves")
    with pytest.raises(ConfigError, match="not one of"):
        GraphEACO(construction="walk")
    with pytest.raises(ValueError, match="kind='3opt' is not one of"):
        construct_tours_moves(jax.random.key(0), jnp.ones((150, 8)), p.neighbors,
                              jnp.arange(150), 1, 2, kind="3opt")


def test_new_only_keeps_a_chain_of_moves_from_putting_back_the_reference_edges():
    # trails that favour the reference tour (as they do once a colony has converged): a chain
    # of moves then mostly restores the reference edges its previous moves removed, unless
    # every move must insert an edge the reference lacks (construction "moves-new")
    p, _, _ = _setup()
    xy = np.random.default_rng(0).integers(0, 10_000, (N, 2))  # _setup's coordinates
    ref, left = [0], set(range(1, N))  # a nearest-neighbour tour: its edges are candidates
    while left:
        nxt = min(left, key=lambda c: float(np.hypot(*(xy[c] - xy[ref[-1]]))))
        ref.append(nxt)
        left.remove(nxt)
    ref = np.asarray(ref, np.int32)
    cands = np.asarray(p.neighbors)
    pos = np.empty(N, np.int64)
    pos[ref] = np.arange(N)
    near = (cands == ref[(pos + 1) % N][:, None]) | (cands == ref[(pos - 1) % N][:, None])
    cand_w = np.where(near, 1e6, 1.0).astype(np.float32)
    counts = {}
    for new_only in (False, True):
        tours = _build(ref, cand_w, cands, 16, new_only=new_only)
        for t in tours:
            assert sorted(t) == list(range(N))
        counts[new_only] = np.mean([len(_edges(t) - _edges(ref)) for t in tours])
    assert counts[True] >= 2 * counts[False], counts
    strategy = GraphEACO(num_ants=M, local_search="none", construction="moves-new",
                         max_new_edges=4)
    assert strategy.construction == "moves-new"


@pytest.mark.parametrize(("kind", "walk"), KINDS)
@pytest.mark.parametrize("new_only", [False, True])
def test_pieces_plan_builds_the_arrays_plans_tours(kind, walk, new_only):
    """The reference under a piecewise map of positions gives the very tours of rewriting
    the (n,) arrays at every move: many moves (many pieces, splits at both ends of every
    stretch, wrap-around), the greedy and the random rule, with a chaos factor."""
    p, ref, cand_w = _setup(3)
    factor = jnp.asarray(np.random.default_rng(4).uniform(0.5, 1.5, (M, N)), jnp.float32)
    for n_moves, q0, fac in ((1, 0.0, None), (7, 0.5, None), (40, 0.2, factor)):
        args = dict(walk=walk, key=n_moves, q0=q0, kind=kind, new_only=new_only, segment=5,
                    factor=fac)
        np.testing.assert_array_equal(
            _build(ref, cand_w, p.neighbors, n_moves, plan="pieces", **args),
            _build(ref, cand_w, p.neighbors, n_moves, plan="arrays", **args))


def test_a_colony_with_the_pieces_plan_runs_the_same_iterations():
    p, _, _ = _setup(5)
    runs = []
    for plan in ("arrays", "pieces"):
        colony = GraphEACO(num_ants=8, max_new_edges=6, construction="moves-new",
                           local_search="2opt", moves_plan=plan)
        state = colony.init(jax.random.key(0), p)
        for i in range(3):
            tours, _ = colony.ask(jax.random.key(i + 1), state, p)
            state, _ = colony.tell(state, tours, p.evaluate(tours), p)
        runs.append(np.asarray(tours))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert GraphEACO().moves_plan == "pieces"  # the default
    with pytest.raises(ConfigError, match="moves_plan"):
        GraphEACO(moves_plan="list")
