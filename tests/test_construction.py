"""Tour construction (Eq. 2, tabu masks, q0 rule, candidate lists) and the logistic map."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from eaco_jax.ops import chaos
from eaco_jax.ops.construction import (
    choice_weights,
    construct_tours,
    greedy_tour,
    heuristic_log_eta,
    tour_lengths,
)


def _instance(n: int = 12, seed: int = 0):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 100, (n, 2))
    d = np.rint(np.linalg.norm(xy[:, None] - xy[None], axis=-1))
    np.fill_diagonal(d, 0)
    d = np.maximum(d, np.where(np.eye(n), 0, 1))
    tau = rng.uniform(0.5, 1.5, (n, n))
    tau = (tau + tau.T) / 2
    nbr = np.argsort(np.where(np.eye(n), np.inf, d), axis=1)[:, :4].astype(np.int32)
    return jnp.asarray(d, jnp.float32), jnp.asarray(tau, jnp.float32), jnp.asarray(nbr)


def _is_perm(tours: np.ndarray) -> bool:
    n = tours.shape[1]
    return bool(np.all(np.sort(tours, axis=1) == np.arange(n)))


@pytest.mark.parametrize("use_candidates", [False, True])
def test_every_tour_is_a_permutation_from_its_start(use_candidates):
    d, tau, nbr = _instance()
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    starts = jnp.arange(30, dtype=jnp.int32) % 12
    tours = np.asarray(construct_tours(
        jax.random.key(1), w, starts, q0=0.3, candidates=nbr if use_candidates else None))
    assert tours.shape == (30, 12) and tours.dtype == np.int32
    assert _is_perm(tours)
    np.testing.assert_array_equal(tours[:, 0], np.asarray(starts))


@pytest.mark.parametrize("use_candidates", [False, True])
def test_tabu_respected_even_when_a_visited_node_dominates(use_candidates):
    """Node 0 has overwhelming weight from everywhere; once visited it must never recur."""
    d, tau, nbr = _instance()
    tau = tau.at[:, 0].set(1e6)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 1.0)
    tours = np.asarray(construct_tours(jax.random.key(2), w, jnp.zeros(8, jnp.int32), q0=0.0,
                                       candidates=nbr if use_candidates else None))
    assert _is_perm(tours)
    assert np.all(tours[:, 0] == 0)


def _numpy_greedy(w: np.ndarray, start: int) -> list[int]:
    n = w.shape[0]
    tour, seen = [start], {start}
    for _ in range(n - 1):
        row = np.where([j in seen for j in range(n)], -np.inf, w[tour[-1]])
        nxt = int(np.argmax(row))
        tour.append(nxt)
        seen.add(nxt)
    return tour


def test_q0_one_gives_the_greedy_argmax_tour():
    d, tau, _ = _instance()
    alpha, beta = 1.0, 2.0
    raw = np.asarray(tau, np.float64) ** alpha * (1.0 / np.maximum(np.asarray(d), 0.5)) ** beta
    np.fill_diagonal(raw, 0)
    w = choice_weights(tau, heuristic_log_eta(d), alpha, beta)
    tours = np.asarray(construct_tours(jax.random.key(3), w, jnp.arange(12, dtype=jnp.int32),
                                       q0=1.0))
    for s in range(12):
        assert tours[s].tolist() == _numpy_greedy(raw, s)
    assert np.asarray(greedy_tour(w, 5)).tolist() == _numpy_greedy(raw, 5)


def test_first_step_follows_eq2_probabilities():
    """Empirical next-node frequencies from node 0 match tau^a eta^b / sum over allowed."""
    d, tau, _ = _instance(n=6, seed=4)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 1.0)
    m = 20000
    tours = np.asarray(construct_tours(jax.random.key(4), w, jnp.zeros(m, jnp.int32), q0=0.0))
    freq = np.bincount(tours[:, 1], minlength=6) / m
    raw = np.asarray(tau[0], np.float64) / np.asarray(d[0], np.float64).clip(0.5)
    raw[0] = 0
    np.testing.assert_allclose(freq, raw / raw.sum(), atol=0.015)


@pytest.mark.parametrize("use_candidates", [False, True])
def test_first_step_mixes_greedy_and_eq2_by_q0(use_candidates):
    """With 0 < q0 < 1 the next node is the greedy one with probability q0 and an Eq. 2 draw
    otherwise (one uniform per ant serves both), over all nodes or over the candidates."""
    d, tau, nbr = _instance(n=10, seed=6)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    cands = nbr[:, :4] if use_candidates else None
    m, q0 = 20000, 0.3
    tours = np.asarray(construct_tours(jax.random.key(6), w, jnp.zeros(m, jnp.int32), q0=q0,
                                       candidates=cands))
    freq = np.bincount(tours[:, 1], minlength=10) / m
    raw = np.asarray(w[0], np.float64).copy()
    if use_candidates:
        keep = np.zeros(10, bool)
        keep[np.asarray(cands[0])] = True
        raw[~keep] = 0
    p = (1 - q0) * raw / raw.sum()
    p[np.argmax(raw)] += q0
    np.testing.assert_allclose(freq, p, atol=0.015)


def test_candidate_step_samples_only_allowed_candidates_and_falls_back_to_best():
    d, tau, nbr = _instance(n=10, seed=5)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    tours = np.asarray(construct_tours(jax.random.key(5), w, jnp.zeros(500, jnp.int32),
                                       q0=0.0, candidates=nbr))
    # first move from node 0 is always one of its candidates
    assert set(np.unique(tours[:, 1])) <= set(np.asarray(nbr[0]).tolist())
    assert _is_perm(tours)


@pytest.mark.parametrize("starts", [[0, 9], list(range(14))])
@pytest.mark.parametrize("chaos", [False, True])
def test_greedy_on_candidates_falls_back_to_whole_row(starts, chaos):
    """q0 = 1 with candidate lists: the best allowed candidate; when all are tabu, the best
    allowed node of the whole row (checked against numpy). 14 ants have more than
    FALLBACK_ANTS ants to rescue at once on some steps, two never do; the chaos factor
    scales the weights in both paths."""
    n = 14
    d, tau, _ = _instance(n=n, seed=7)
    order = np.argsort(np.where(np.eye(n), np.inf, np.asarray(d)), axis=1)
    nbr = order[:, :3].astype(np.int32)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    m = len(starts)
    factor = (np.random.default_rng(1).uniform(0.5, 1.5, (m, n)).astype(np.float32)
              if chaos else np.ones((m, n), np.float32))
    tours = np.asarray(construct_tours(
        jax.random.key(7), w, jnp.asarray(starts, jnp.int32), q0=1.0,
        factor=jnp.asarray(factor) if chaos else None, candidates=jnp.asarray(nbr)))
    wn = np.asarray(w, np.float32)
    for a, s in enumerate(starts):
        tour, seen = [s], {s}
        for _ in range(n - 1):
            c = tour[-1]
            allowed = [j for j in nbr[c] if j not in seen] or [
                j for j in range(n) if j not in seen]
            nxt = max(allowed, key=lambda j: wn[c, j] * factor[a, j])
            tour.append(nxt)
            seen.add(nxt)
        assert tours[a].tolist() == tour


def test_row_offset_lets_one_ant_use_other_weights():
    d, tau, _ = _instance()
    w1 = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    w2 = choice_weights(tau, heuristic_log_eta(d), 1.0, 0.0)  # pheromone only
    stacked = jnp.concatenate([w1, w2])
    tours = construct_tours(jax.random.key(6), stacked, jnp.zeros(2, jnp.int32), q0=1.0,
                            row_offset=jnp.array([0, 12], jnp.int32))
    assert np.array_equal(tours[0], greedy_tour(w1, 0))
    assert np.array_equal(tours[1], greedy_tour(w2, 0))


def test_chaos_factor_changes_choices_and_keeps_permutations():
    d, tau, _ = _instance()
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    starts = jnp.zeros(16, jnp.int32)
    x = chaos.logistic_init(jax.random.key(7), (16, 12))
    plain = construct_tours(jax.random.key(8), w, starts, q0=1.0)
    shaken = construct_tours(jax.random.key(8), w, starts, q0=1.0,
                             factor=chaos.perturbation(x, jnp.float32(0.9)))
    assert _is_perm(np.asarray(shaken))
    assert not np.array_equal(plain, shaken)


def test_logistic_map_stays_inside_and_keeps_moving():
    x = jnp.array([0.5, 0.75, 0.25, 1e-7, 0.3], jnp.float32)
    seen = []
    for _ in range(200):
        x = chaos.logistic_step(x)
        seen.append(np.asarray(x))
    seen = np.array(seen)
    assert np.all((seen > 0) & (seen < 1))
    assert np.all(np.std(seen[-50:], axis=0) > 0.05)  # no absorbing / fixed point
    np.testing.assert_allclose(chaos.logistic_step(jnp.float32(0.3)), 4 * 0.3 * 0.7, rtol=1e-6)


def test_tour_lengths_and_weights_underflow_safe():
    d, tau, _ = _instance()
    tours = jnp.stack([jnp.arange(12), jnp.arange(12)[::-1]]).astype(jnp.int32)
    want = [sum(float(d[t[i], t[(i + 1) % 12]]) for i in range(12)) for t in np.asarray(tours)]
    np.testing.assert_allclose(tour_lengths(d, tours), want)
    w = choice_weights(tau * 1e-30, heuristic_log_eta(d * 1e4), 1.0, 12.0)
    assert np.all(np.isfinite(w)) and np.allclose(np.max(w, axis=1), 1.0)
    assert np.all(np.diag(np.asarray(w)) == 0)


@pytest.mark.parametrize("chaos_on", [False, True])
@pytest.mark.parametrize("backup,div", [(64, 8), (4, 8), (4, 2), (64, 1000)])
def test_every_fallback_plan_builds_the_same_tours(chaos_on, backup, div, monkeypatch):
    """The whole-row fallback's plans (lazy branch, dense, backup list + compaction) differ in
    cost only: same tours, bit for bit, with many ants falling back on short candidate lists,
    two stacked weight matrices, the q0 mix and (where the backup list is off) chaos. A
    backup list of 4 leaves many ants to the compacted whole-row search."""
    from eaco_jax.ops import construction

    monkeypatch.setattr(construction, "BACKUP", backup)
    monkeypatch.setattr(construction, "COMPACT_DIV", div)  # "compact": every branch taken
    n, m = 60, 50
    d, tau, _ = _instance(n=n, seed=11)
    nbr = np.argsort(np.where(np.eye(n), np.inf, np.asarray(d)), axis=1)[:, :3]
    le = heuristic_log_eta(d)
    stacked = jnp.concatenate([choice_weights(tau, le, 1.0, 2.0),
                               choice_weights(tau, le, 1.0, 0.0)], axis=0)
    rng = np.random.default_rng(3)
    starts = jnp.asarray(rng.integers(0, n, m), jnp.int32)
    offset = jnp.asarray(np.where(np.arange(m) % 7 == 0, n, 0), jnp.int32)
    q0 = jnp.asarray(np.where(np.arange(m) % 3 == 0, 0.9, 0.2), jnp.float32)
    factor = jnp.asarray(rng.uniform(0.8, 1.2, (m, n)), jnp.float32) if chaos_on else None
    built = {plan: np.asarray(construct_tours(jax.random.key(4), stacked, starts, q0, offset,
                                              factor, jnp.asarray(nbr, jnp.int32), plan))
             for plan in ("lazy", "dense", "backup", "compact", "kernel")}
    assert _is_perm(built["lazy"])
    np.testing.assert_array_equal(built["dense"], built["lazy"])
    np.testing.assert_array_equal(built["backup"], built["lazy"])
    np.testing.assert_array_equal(built["compact"], built["lazy"])
    np.testing.assert_array_equal(built["kernel"], built["lazy"])  # 2 programs, 14 padded ants
    with pytest.raises(ValueError, match="fallback"):
        construct_tours(jax.random.key(4), stacked, starts, candidates=jnp.asarray(nbr),
                        fallback="sometimes")
    with pytest.raises(ValueError, match="kernel.*candidate lists"):
        construct_tours(jax.random.key(4), stacked, starts, fallback="kernel")
    big = jax.ShapeDtypeStruct((2**31 // n + 64,), jnp.int32)  # traced only, never built
    with pytest.raises(ValueError, match="int32.*fewer ants"):
        jax.eval_shape(lambda s: construct_tours(jax.random.key(4), stacked, s,
                                                 candidates=jnp.asarray(nbr), fallback="kernel"),
                       big)


def test_compaction_is_nonzero():
    from eaco_jax.ops.construction import _compact

    rng = np.random.default_rng(0)
    for p in (0.0, 0.1, 0.5, 1.0):
        mask = jnp.asarray(rng.random(37) < p)
        for size in (1, 5, 37, 50):
            np.testing.assert_array_equal(
                _compact(mask, size, 99), jnp.nonzero(mask, size=size, fill_value=99)[0])


@pytest.mark.parametrize("n", [5, 31, 32, 33, 64, 100])
def test_compact_plan_bit_mask(n):
    """The compact plan's tabu bit mask: packing round-trips, a word gather tests one node,
    and with 5-nearest candidate lists the plan builds the dense plan's tours at every n
    (one word, a whole last word, a partial last word)."""
    from eaco_jax.ops.construction import _pack_bits, _test_bits, _unpack_bits

    rng = np.random.default_rng(n)
    alive = jnp.asarray(rng.random((7, n)) < 0.5)
    bits = _pack_bits(alive)
    assert bits.shape == (7, -(-n // 32)) and bits.dtype == jnp.uint32
    np.testing.assert_array_equal(_unpack_bits(bits, n), alive)
    nodes = jnp.asarray(rng.integers(0, n, (7, 4)), jnp.int32)
    np.testing.assert_array_equal(_test_bits(bits, jnp.arange(7), nodes),
                                  np.take_along_axis(np.asarray(alive), np.asarray(nodes), 1))
    if n < 8:
        return
    d, tau, _ = _instance(n=n, seed=n)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    nbr = jnp.asarray(np.argsort(np.where(np.eye(n), np.inf, np.asarray(d)), axis=1)[:, :5],
                      jnp.int32)
    starts = jnp.asarray(rng.integers(0, n, 40), jnp.int32)
    tours = {p: np.asarray(construct_tours(jax.random.key(n), w, starts, 0.3, candidates=nbr,
                                           fallback=p)) for p in ("dense", "compact", "kernel")}
    assert _is_perm(tours["compact"]) and _is_perm(tours["kernel"])
    np.testing.assert_array_equal(tours["compact"], tours["dense"])
    np.testing.assert_array_equal(tours["kernel"], tours["dense"])


def test_backup_list_is_the_whole_row_order():
    from eaco_jax.ops.construction import _backup_lists, _packed_argmax

    d, tau, _ = _instance(n=20, seed=2)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    nodes, positive = _backup_lists(w, 6)
    alive = np.ones(20, bool)
    for r in range(20):
        mask = alive.copy()
        mask[np.asarray(nodes[r, :3])] = False  # the three heaviest are tabu
        best, ok = _packed_argmax(jnp.where(jnp.asarray(mask), w[r], 0.0))
        assert bool(ok) and bool(positive[r, 3]) and int(best) == int(nodes[r, 3])


@pytest.mark.parametrize("block", [16, 64])
def test_kernel_plan_blocks_and_greedy(block, monkeypatch):
    """The kernel plan at other block sizes (several programs, or one partly padded) builds
    the lazy plan's tours, the q0 = 1 greedy tours included; one ant works too."""
    from eaco_jax.ops import construction_kernel

    monkeypatch.setattr(construction_kernel, "BLOCK", block)
    n, m = 45, 70
    d, tau, _ = _instance(n=n, seed=5)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    nbr = jnp.asarray(np.argsort(np.where(np.eye(n), np.inf, np.asarray(d)), axis=1)[:, :4],
                      jnp.int32)
    starts = jnp.asarray(np.random.default_rng(1).integers(0, n, m), jnp.int32)
    for q0 in (0.0, 1.0):
        want, got = (np.asarray(construct_tours(jax.random.key(7), w, starts, q0,
                                                candidates=nbr, fallback=p))
                     for p in ("lazy", "kernel"))
        assert _is_perm(got)
        np.testing.assert_array_equal(got, want)
    one = construct_tours(jax.random.key(7), w, starts[:1], 0.5, candidates=nbr,
                          fallback="kernel")
    np.testing.assert_array_equal(one, construct_tours(jax.random.key(7), w, starts[:1], 0.5,
                                                       candidates=nbr, fallback="lazy"))


@pytest.mark.skipif(jax.default_backend() != "gpu", reason="needs a GPU (Triton)")
def test_kernel_plan_on_the_gpu_builds_the_scan_plans_tours():
    """Compiled by Triton, the kernel builds the compact plan's tours for 4,096 ants on
    pcb442 with chaos off and on."""
    import eaco_jax as ea

    p = ea.problems.get("pcb442")
    w = choice_weights(jnp.ones((p.n, p.n)), heuristic_log_eta(p.dist), 1.0, 2.0)
    starts = jax.random.randint(jax.random.key(1), (4096,), 0, p.n, jnp.int32)
    factor = jax.random.uniform(jax.random.key(2), (4096, p.n), minval=0.9, maxval=1.1)
    for f in (None, factor):
        a, b = (construct_tours(jax.random.key(3), w, starts, 0.1, None, f, p.neighbors, plan)
                for plan in ("compact", "kernel"))
        assert float(jnp.mean(jnp.all(a == b, axis=1))) == 1.0


def test_auto_runs_the_backends_row_of_the_plan_table(monkeypatch):
    """fallback="auto" runs the plan AUTO_PLANS names for the backend: on a CPU "lazy", whose
    steps branch (a cond) only where some ant needs its whole row; a table naming "dense" for
    every backend gives the branch-free scan."""
    from eaco_jax.ops import construction

    assert [construction.auto_plan(b) for b in ("cpu", "gpu", "tpu")] == \
        ["lazy", "kernel", "dense"]
    n, m = 12, 5
    d, tau, nbr = _instance(n=n)
    w = choice_weights(tau, heuristic_log_eta(d), 1.0, 2.0)
    starts = jnp.arange(m, dtype=jnp.int32)

    def branches() -> bool:
        jaxpr = jax.make_jaxpr(lambda key: construct_tours(key, w, starts, candidates=nbr))(
            jax.random.key(0))
        return "cond[" in str(jaxpr)

    assert branches() == (jax.default_backend() == "cpu")
    monkeypatch.setattr(construction, "AUTO_PLANS", (construction.PlanRow("*", "dense", "x"),))
    assert construction.auto_plan("cpu") == "dense" and not branches()
