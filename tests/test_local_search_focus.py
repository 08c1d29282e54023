"""The focused batched search (``two_opt(..., active=)``): it starts from the given cities only
and repairs a local optimum that a few changed edges broke, as Focused ACO's ants need."""

from __future__ import annotations

import numpy as np
import pytest

from eaco_jax.ops.local_search import changed_cities, two_opt


def _instance(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    xy = rng.integers(0, 10_000, (n, 2)).astype(np.float64)
    d = np.rint(np.sqrt(((xy[:, None] - xy[None]) ** 2).sum(-1))).astype(np.float32)
    nb = np.argsort(np.where(np.eye(n, dtype=bool), np.inf, d), 1)[:, :10].astype(np.int32)
    return d, nb


def _length(d: np.ndarray, tours) -> np.ndarray:
    t = np.asarray(tours)
    return d[t, np.roll(t, -1, axis=1)].sum(axis=1)


@pytest.fixture(scope="module")
def broken():
    """Local optima of the candidate neighbourhood, each broken by six segment reversals."""
    n, m = 300, 3
    d, nb = _instance(n)
    rng = np.random.default_rng(1)
    start = np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32)
    opt = np.asarray(two_opt(start, d, nb, or_opt=True))
    pert = opt.copy()
    for row in pert:
        for _ in range(6):
            a, b = sorted(rng.choice(n, 2, replace=False))
            row[a:b] = row[a:b][::-1].copy()
    focus = np.stack([np.asarray(changed_cities(pert[i:i + 1], opt[i]))[0] for i in range(m)])
    return d, nb, opt, pert, focus


@pytest.mark.parametrize("or_opt", [False, True])
def test_focused_search_repairs_the_broken_edges_to_a_local_optimum(broken, or_opt):
    d, nb, _, pert, focus = broken
    assert 0 < focus.sum(axis=1).max() <= 24  # a few cities, not n
    out, moves, steps = two_opt(pert, d, nb, or_opt=or_opt, active=focus, focus_width=8,
                                return_steps=True)
    out = np.asarray(out)
    assert all(sorted(t) == list(range(d.shape[0])) for t in out)
    assert np.all(_length(d, out) < _length(d, pert))
    assert np.all(np.asarray(steps) > 1)  # width 8 < the active cities: several steps
    # nothing left for the unfocused search to find: the repair reached a local optimum
    _, left = two_opt(out, d, nb, or_opt=or_opt, return_moves=True)
    assert np.all(np.asarray(left) == 0)


def test_focused_search_with_no_active_city_leaves_the_tours_alone(broken):
    d, nb, _, pert, focus = broken
    out = two_opt(pert, d, nb, or_opt=True, active=np.zeros_like(focus))
    np.testing.assert_array_equal(np.asarray(out), pert)


def test_focused_search_from_every_city_matches_the_full_search_closely(broken):
    d, nb, _, pert, _ = broken
    n = d.shape[0]
    rng = np.random.default_rng(2)
    tours = np.stack([rng.permutation(n) for _ in range(3)]).astype(np.int32)
    full = _length(d, two_opt(tours, d, nb, or_opt=True))
    focused = _length(d, two_opt(tours, d, nb, or_opt=True, active=np.ones_like(tours, bool),
                                 focus_width=n))
    assert np.all(focused < _length(d, tours))
    assert abs(focused.mean() / full.mean() - 1) < 0.03


def test_active_of_the_wrong_shape_is_refused(broken):
    d, nb, _, pert, focus = broken
    with pytest.raises(ValueError, match="active must have the tours' shape"):
        two_opt(pert, d, nb, active=focus[:, :10])


def test_a_move_wakes_the_ends_of_the_edges_it_removed(broken):
    """From one active city of a random tour the search spreads along the edges its moves
    change: far more moves than that one city alone could make."""
    d, nb, _, _, _ = broken
    n = d.shape[0]
    tours = np.random.default_rng(3).permutation(n).astype(np.int32)[None]
    one = np.zeros((1, n), bool)
    one[0, tours[0, 0]] = True
    out, moves = two_opt(tours, d, nb, or_opt=True, active=one, focus_width=16,
                         return_moves=True)
    assert int(np.asarray(moves)[0]) > n // 2
    assert _length(d, out)[0] < 0.5 * _length(d, tours)[0]


@pytest.fixture(scope="module")
def uneven():
    """Nine broken local optima, broken by 1 to 9 reversals: searches of uneven length."""
    n, m = 200, 9
    d, nb = _instance(n, 3)
    rng = np.random.default_rng(4)
    opt = np.asarray(two_opt(np.stack([rng.permutation(n) for _ in range(m)]).astype(np.int32),
                             d, nb, or_opt=True))
    pert = opt.copy()
    for i, row in enumerate(pert):
        for _ in range(i + 1):
            a, b = sorted(rng.choice(n, 2, replace=False))
            row[a:b] = row[a:b][::-1].copy()
    focus = np.stack([np.asarray(changed_cities(pert[i:i + 1], opt[i]))[0] for i in range(m)])
    return d, nb, pert, focus


@pytest.mark.parametrize("loop", ["ants", "colony"])
@pytest.mark.parametrize("compact", [(0, 1), (1, 2), (2, 4), (3, 9), (2, 20)])
def test_compacted_focused_search_gives_the_same_tours_moves_and_steps(uneven, compact, loop):
    d, nb, pert, focus = uneven
    want = [np.asarray(x) for x in two_opt(pert, d, nb, or_opt=True, active=focus,
                                           focus_width=4, return_steps=True)]
    assert want[2].max() > 2 * max(compact[0], 1) and want[2].min() < want[2].max()
    got = [np.asarray(x) for x in two_opt(pert, d, nb, or_opt=True, active=focus,
                                          focus_width=4, return_steps=True, compact=compact,
                                          loop=loop)]
    for w, g in zip(want, got, strict=True):
        np.testing.assert_array_equal(g, w)


def test_compact_refuses_a_batch_below_one(uneven):
    from eaco_jax.errors import ConfigError

    d, nb, pert, focus = uneven
    with pytest.raises(ConfigError, match="batch >= 1"):
        two_opt(pert, d, nb, active=focus, compact=(2, 0))


def test_a_colony_with_ls_compact_builds_the_same_tours():
    import dataclasses

    import jax

    from eaco_jax.errors import ConfigError
    from eaco_jax.problems.tsp_sparse import SparseTSP
    from eaco_jax.strategies.graph_eaco import GraphEACO

    xy = np.random.default_rng(5).integers(0, 10_000, (150, 2))
    problem = SparseTSP.from_coords(xy, neighbors=8)
    plain = GraphEACO(num_ants=6, local_search="or-2opt", preset="mmas", max_new_edges=16,
                      construction="moves-new", ls_focus_width=4)
    compact = dataclasses.replace(plain, ls_compact=[1, 2])  # a list, as from JSON
    assert compact.ls_compact == (1, 2)
    state = plain.init(jax.random.key(0), problem)
    a, _ = plain.ask(jax.random.key(1), state, problem)
    b, _ = compact.ask(jax.random.key(1), state, problem)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    with pytest.raises(ConfigError, match="ls_compact"):
        GraphEACO(ls_compact=(1, 0))


@pytest.mark.parametrize("or_opt", [False, True])
def test_a_step_names_exactly_the_cities_whose_tour_neighbours_changed(or_opt):
    # the focused step wakes the ends of the removed edges it is told of (_apply_disjoint's
    # ends), not every city whose neighbours it compares: those must be the same cities, for
    # reversals and for both kinds of segment move
    import jax.numpy as jnp

    from eaco_jax.ops import local_search as ls

    n = 200
    d, nb = _instance(n, seed=4)
    dist, cand = jnp.asarray(d), jnp.asarray(nb)
    cand_d = dist[jnp.arange(n)[:, None], cand]
    rng = np.random.default_rng(2)
    kinds = set()
    for _ in range(12):
        tour = jnp.asarray(rng.permutation(n).astype(np.int32))
        pos = jnp.zeros(n, jnp.int32).at[tour].set(jnp.arange(n, dtype=jnp.int32))
        succ, pred = tour[(pos + 1) % n], tour[(pos - 1) % n]
        two = ls._two_opt_moves(pos, succ, pred, dist, cand, cand_d)
        orr = ls._or_opt_moves(tour, pos, succ, pred, dist, cand, cand_d) if or_opt else None
        if orr is not None:  # Or-opt moves only, so that both of their kinds get applied
            two = (jnp.full_like(two[0], -jnp.inf), two[1], two[2])
            kinds |= set(np.asarray(orr[3])[np.isfinite(np.asarray(orr[0]))].tolist())
        new, new_pos, applied, cut = ls._apply_proposals(tour, pos, two, orr, 16,
                                                         jnp.int32(10**6), "rounds", ends=True)
        old, new = np.asarray(tour), np.asarray(new)
        assert sorted(new.tolist()) == list(range(n)) and int(applied) > 0
        np.testing.assert_array_equal(np.asarray(new_pos)[new], np.arange(n))

        def pairs(t):
            p = np.empty(n, np.int64)
            p[t] = np.arange(n)
            return {c: frozenset((t[(p[c] + 1) % n], t[(p[c] - 1) % n])) for c in range(n)}

        before, after = pairs(old), pairs(new)
        changed = {c for c in range(n) if before[c] != after[c]}
        named = set(np.asarray(cut).tolist()) - {n}
        assert named == changed
    if or_opt:
        assert kinds >= {ls.SEGMENT_TO_END, ls.SEGMENT_TO_FRONT}


@pytest.mark.parametrize("max_moves", [None, 6])
def test_the_colony_loop_gives_the_same_tours_moves_and_steps(uneven, max_moves):
    """One loop over the colony's steps (no per-ant select) against the vmapped loop: the
    same tours, moves and steps for searches of uneven length, an ant with no active city,
    and ants stopped by the move cap."""
    d, nb, pert, focus = uneven
    focus = focus.copy()
    focus[0] = False  # an ant that does not search at all
    args = dict(or_opt=True, active=focus, focus_width=4, return_steps=True)
    want = [np.asarray(x) for x in two_opt(pert, d, nb, max_moves, **args)]
    assert want[2][0] == 0 and want[2].min() < want[2][1:].max()
    got = [np.asarray(x) for x in two_opt(pert, d, nb, max_moves, loop="colony", **args)]
    for w, g in zip(want, got, strict=True):
        np.testing.assert_array_equal(g, w)


def test_a_colony_with_ls_loop_colony_builds_the_same_tours():
    import dataclasses

    import jax

    from eaco_jax.errors import ConfigError
    from eaco_jax.problems.tsp_sparse import SparseTSP
    from eaco_jax.strategies.graph_eaco import GraphEACO

    xy = np.random.default_rng(6).integers(0, 10_000, (150, 2))
    problem = SparseTSP.from_coords(xy, neighbors=8)
    plain = GraphEACO(num_ants=6, local_search="or-2opt", preset="mmas", max_new_edges=16,
                      construction="moves-new", ls_focus_width=4, ls_loop="ants")
    assert GraphEACO().ls_loop == "colony"  # the default; "ants" is the reference here
    state = plain.init(jax.random.key(0), problem)
    a, _ = plain.ask(jax.random.key(1), state, problem)
    b, _ = dataclasses.replace(plain, ls_loop="colony").ask(jax.random.key(1), state, problem)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    c, _ = dataclasses.replace(plain, ls_loop="colony", ls_acceptance="unrolled").ask(
        jax.random.key(1), state, problem)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(c))
    # the setting reaches the search: its program differs (the rounds inline), not its tours
    progs = [str(jax.make_jaxpr(lambda k, s, g=g: g.ask(k, s, problem))(jax.random.key(1), state))
             for g in (dataclasses.replace(plain, ls_loop="colony"),
                       dataclasses.replace(plain, ls_loop="colony", ls_acceptance="unrolled"))]
    assert progs[0] != progs[1]
    with pytest.raises(ConfigError, match="ls_loop"):
        GraphEACO(ls_loop="threads")
    with pytest.raises(ConfigError, match="ls_acceptance"):
        GraphEACO(ls_acceptance="greedy")


def test_each_step_evaluates_the_first_set_bits_of_the_mask_it_carries(broken):
    """A step's cities and the count of set bits are carried from the step before (so that
    the loop's test reads the count instead of reducing all n bits again): they must be those
    of the bits as that step left them, every step, and the steps are the public search's."""
    import jax

    from eaco_jax.ops import local_search as ls
    from eaco_jax.ops.compaction import blocks_of, first_true

    d, nb, _, pert, focus = broken
    n, width = d.shape[0], 8
    dist = ls.as_distances(d)
    cand = ls._candidates(dist, nb)
    cand_d = dist[np.arange(n)[:, None], cand]
    body, live = ls._focused_fns(dist, cand, cand_d, 4 * n, 32, True, "rounds", width, n)
    body, live = jax.jit(body), jax.jit(live)
    focus = focus.copy()
    focus[:, n - 1] = True  # the last city too: its bit is set from the "no city" index's
    out, _, steps = two_opt(pert, d, nb, or_opt=True, active=focus, focus_width=width,
                            return_steps=True)
    for i in range(len(pert)):
        tour = np.asarray(pert[i], np.int32)
        active = np.zeros(blocks_of(n), bool)  # as the search holds them: padded with False
        active[:n] = focus[i]
        at, count = first_true(active, width, 0)
        carry = (tour, np.argsort(tour).astype(np.int32), active, at, count, np.int32(0),
                 np.int32(0))
        while bool(live(carry)):
            carry = body(carry)
            at, count = first_true(carry[2], width, 0)
            np.testing.assert_array_equal(np.asarray(carry[3]), np.asarray(at))
            assert int(carry[4]) == int(count)
            assert not np.asarray(carry[2])[n:].any()  # no bit past the cities
        assert int(carry[6]) == int(np.asarray(steps)[i]) > 1
        np.testing.assert_array_equal(np.asarray(carry[0]), np.asarray(out)[i])
