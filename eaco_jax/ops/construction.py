"""Tour construction on a construction graph: the whole colony in one ``lax.scan``.

Each ant starts at a node and adds one node per step. At node i with tabu set (visited nodes)
T_k it chooses the next node j

* greedily, j = argmax_{u not in T_k} tau_iu^alpha eta_iu^beta, with probability q0
  (the pseudo-random proportional rule of ACS, Table 3's ``q0``), otherwise
* at random with p_ij proportional to tau_ij^alpha eta_ij^beta over j not in T_k (Eq. 2).

The choice weights may be multiplied by a per-ant chaos factor (see :mod:`eaco_jax.ops.chaos`).
All ants move together: one scan step is a batched gather of the current rows of the weight
matrix (or of the k candidate columns, see ``candidates``), a tabu mask (``alive``: 1 for
nodes still to visit, 0 for visited ones), prefix sums and one uniform draw per ant, used for
both the q0 rule and inverse-CDF sampling; there is no Python loop over ants or steps. The
uniforms of all steps are drawn in one call before the scan, a row per step (XLA:CPU pays a
cost per operation inside a loop, so fewer, larger operations are faster).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from eaco_jax.ops.compaction import first_true
from eaco_jax.ops.packed_keys import bit_allowed, id_bits, packed_keys

Array = jax.Array
#: construction steps per loop iteration of the compiled scan (fewer loop round-trips on CPU)
UNROLL = 2
#: rows up to this length (candidate lists) take prefix sums as a matmul, longer ones cumsum
MATMUL_CUMSUM = 64
#: on CPU, steps where at most this many ants have all candidates tabu search only those
#: ants' whole rows (more: every ant's)
FALLBACK_ANTS = 4
#: on accelerators, length of each row's backup list (its heaviest nodes) for the fallback
BACKUP = 64
#: plan "compact": at most m // COMPACT_DIV ants per step take the fallback through one
#: compaction (their backup lists), and at most that // COMPACT_DIV of them their whole rows;
#: other pending ants wait a step (exact: each ant draws the uniform of its tour position)
COMPACT_DIV = 8


def choice_weights(tau: Array, log_eta: Array, alpha: Array, beta: Array) -> Array:
    """tau^alpha * eta^beta per edge, each row scaled so its largest off-diagonal entry is 1.

    Computed in log space (``log_eta`` = log(1/d), -inf on the diagonal) so that large beta and
    long edges do not underflow float32; row scaling leaves Eq. 2's probabilities unchanged.
    """
    off = jnp.isfinite(log_eta)
    logw = alpha * jnp.log(tau) + beta * jnp.where(off, log_eta, 0.0)
    logw = jnp.where(off, logw, -jnp.inf)
    logw = logw - jnp.max(logw, axis=1, keepdims=True)
    return jnp.exp(logw).astype(jnp.float32)


def heuristic_log_eta(dist: Array) -> Array:
    """log(eta) = -log(d_ij) (Eq. 1), -inf on the diagonal; zero distances count as 0.5."""
    n = dist.shape[0]
    d = jnp.maximum(dist.astype(jnp.float32), 0.5)
    log_eta = -jnp.log(d)
    return jnp.where(jnp.eye(n, dtype=bool), -jnp.inf, log_eta)


def _packed_argmax(score: Array) -> tuple[Array, Array]:
    """(argmax, max > 0) of non-negative float scores along the last axis as ONE int32 max of
    :func:`~eaco_jax.ops.packed_keys.packed_keys` (XLA:CPU's variadic argmax reduce is several
    times slower)."""
    width = score.shape[-1]
    low = id_bits(width)
    best = jnp.max(packed_keys(score, jnp.arange(width, dtype=jnp.int32), low), axis=-1)
    return best & ((1 << low) - 1), (best >> low) > 0


def _sample(w: Array, u: Array, q0: Array) -> tuple[Array, Array]:
    """Index chosen by the q0 rule and Eq. 2 from weights ``w`` (m, k) (tabu entries 0) with
    one uniform ``u`` per ant, and whether any weight is positive.

    ``u < q0``: the greedy argmax. Otherwise ``v = (u - q0) / (1 - q0)`` is uniform on [0, 1)
    again and picks by inverse CDF: the number of prefix sums below ``v * total``. For short
    rows (candidate lists) the prefix sums are one small matmul with a triangular matrix and the
    greedy index a packed max (both faster on XLA:CPU than ``cumsum`` / ``argmax``; the packed
    max treats weights within 2^-18 of each other as ties).
    """
    k = w.shape[-1]
    if k <= MATMUL_CUMSUM:
        greedy, ok = _packed_argmax(w)
        # HIGHEST: float32 prefix sums on GPUs too (the default may round through TF32)
        cum = jnp.matmul(w, jnp.triu(jnp.ones((k, k), w.dtype)),
                         precision=jax.lax.Precision.HIGHEST)
    else:  # whole rows: exact argmax, O(k) prefix sums
        greedy, ok = jnp.argmax(w, axis=1).astype(jnp.int32), jnp.any(w > 0, axis=1)
        cum = jnp.cumsum(w, axis=1)
    v = (u - q0) / jnp.maximum(1.0 - q0, 1e-12)
    target = jnp.maximum(v * cum[:, -1], jnp.finfo(w.dtype).tiny)
    sampled = jnp.minimum(jnp.sum(cum < target[:, None], axis=1, dtype=jnp.int32), k - 1)
    # float rounding could land on a zero (tabu) weight: keep the greedy choice then
    hit = jnp.sum(jnp.where(jnp.arange(k) == sampled[:, None], w, 0.0), axis=1)
    sampled = jnp.where(hit > 0, sampled, greedy)
    return jnp.where(u < q0, greedy, sampled), ok


@dataclasses.dataclass(frozen=True)
class PlanRow:
    """One row of :data:`AUTO_PLANS`: the plan ``fallback="auto"`` runs on ``backend`` (a
    ``jax.default_backend()`` name; "*": any other)."""

    backend: str
    plan: str
    claim: str  # the id in experiments/claims.toml whose measurement chose this row


#: the construction plan "auto" runs; the first matching row wins, each naming the claim that
#: justifies it. A CPU pays per operation inside a loop, so its plan branches only on steps
#: where some ant needs the whole-row fallback (construction then keeps ACOTSP's time per
#: iteration); a GPU runs the kernel, one program per block of ants instead of a batched step
#: per tour position; other accelerators the branch-free scan plan. The kernel needs candidate
#: lists: without them a GPU runs "dense" (every scan plan then runs the same whole-row step)
AUTO_PLANS: tuple[PlanRow, ...] = (
    PlanRow("cpu", "lazy", "tsp-speed-core-eil51"),
    PlanRow("gpu", "kernel", "tsp-gpu-kernel-pr1002-16384"),
    PlanRow("*", "dense", "tsp-gpu-dense-over-backup-pr1002-4096"),
)


def auto_plan(backend: str | None = None) -> str:
    """The plan of :data:`AUTO_PLANS` for ``backend`` (default: JAX's default backend)."""
    backend = jax.default_backend() if backend is None else backend
    for row in AUTO_PLANS:
        if row.backend in (backend, "*"):
            return row.plan
    raise AssertionError(f"AUTO_PLANS has no row for {backend}")


def kernel_compiles_here() -> bool:
    """Whether the construction kernel compiles natively on this backend (a GPU, as Triton);
    elsewhere it runs in Pallas' interpreter (slowly: for tests)."""
    return jax.default_backend() == "gpu"


def _row_keys(rows: Array) -> Array:
    """The int32 packed keys of :func:`_packed_argmax` for whole rows (weight bits high,
    column low): their order is the order in which the whole-row fallback prefers nodes."""
    width = rows.shape[-1]
    return packed_keys(rows, jnp.arange(width, dtype=jnp.int32), id_bits(width))


def _backup_lists(weights: Array, size: int) -> tuple[Array, Array]:
    """Each row's ``size`` nodes of largest packed key (descending) and whether their weight
    bits are non-zero. The whole-row fallback picks the allowed node of largest key; when one
    of these nodes is allowed, the first allowed one IS that node (exact, same ties), so only
    ants with all of them tabu need the whole row. One top_k over (R, n) per construction."""
    keys, _ = jax.lax.top_k(_row_keys(weights), size)
    low = id_bits(weights.shape[1])
    return keys & ((1 << low) - 1), (keys >> low) > 0


def _whole_row_best(weights: Array, row_offset: Array, factor: Array | None, ants: Array,
                    current: Array, alive: Array) -> Array:
    """The whole-row fallback (ACOTSP's rule) for ants ``ants`` at ``current`` with tabu masks
    ``alive`` (A, n): the allowed node of largest weight, the first allowed one if all their
    weights are 0. Every plan uses this one rule, which is why they build the same tours."""
    w = jnp.where(alive, weights[row_offset[ants] + current], 0.0)
    w = w if factor is None else w * factor[ants]
    best, ok = _packed_argmax(w)
    return jnp.where(ok, best, jnp.argmax(alive, axis=1).astype(jnp.int32))


def _candidate_tables(weights: Array, candidates: Array, factor: Array | None, backup: int):
    """Per-construction tables of the candidate-list plans: the lists repeated for each
    stacked weight matrix, their choice info, and the backup lists ((None, None) when
    ``backup`` is 0 or a per-ant chaos factor is on: the lists order nodes by weight alone)."""
    copies = weights.shape[0] // weights.shape[1]
    cands = jnp.concatenate([candidates] * copies, axis=0)
    cand_w = jnp.take_along_axis(weights, cands, axis=1)  # choice info, once per construction
    if backup and factor is None:
        return cands, cand_w, *_backup_lists(weights, backup)
    return cands, cand_w, None, None


def _pack_bits(alive: Array) -> Array:
    """(m, n) bool -> (m, ceil(n / 32)) uint32, bit j of word w = node 32 w + j."""
    m, n = alive.shape
    words = -(-n // 32)
    pad = jnp.pad(alive, ((0, 0), (0, 32 * words - n))).reshape(m, words, 32)
    shifts = jnp.arange(32, dtype=jnp.uint32)
    return jnp.sum(pad.astype(jnp.uint32) << shifts, axis=-1, dtype=jnp.uint32)


def _unpack_bits(bits: Array, n: int) -> Array:
    """(A, words) uint32 -> (A, n) bool (inverse of :func:`_pack_bits`)."""
    shifts = jnp.arange(32, dtype=jnp.uint32)
    full = ((bits[:, :, None] >> shifts) & 1).astype(bool)
    return full.reshape(bits.shape[0], -1)[:, :n]


def _test_bits(bits: Array, ants: Array, nodes: Array) -> Array:
    """Whether ``nodes`` (A, k) are still to visit for ``ants`` (A,): one word gather each."""
    return bit_allowed(bits.reshape(-1), ants[:, None] * bits.shape[1], nodes)


def _compact(mask: Array, size: int, fill: int) -> Array:
    """Indices of the first ``size`` True entries of ``mask`` in order, ``fill`` after them
    (``jnp.nonzero`` without its contended scatter-add; :func:`first_true`)."""
    return first_true(mask, size, fill)[0]


def _compact_step(weights: Array, row_offset: Array, q0: Array, factor: Array | None,
                  candidates: Array, uniforms: Array, backup: int, div: int):
    """One construction step of plan "compact" (see :func:`construct_tours`), for a loop
    over ``(current, bits, pos, path)``.

    The tabu set is a bit mask, ``(m, ceil(n / 32))`` uint32 words (8 MB for 65,536 ants of a
    1,002-city tour: it stays in a GPU's L2 cache, where the bool mask, 8x larger, does not);
    the k candidates cost one word gather each. Ants whose candidates are all tabu are
    compacted into ``m // div`` slots: their backup lists first (exact, as plan "backup"),
    then the whole rows of at most ``m // div**2`` ants still left. There is no branch (on a
    GPU a ``cond`` in the loop syncs with the host every step): a pending ant that finds no
    slot waits, at the same node, and moves in a later step. Each ant draws the uniform of
    its own tour position (``uniforms[pos - 1]``), so waiting changes no tour: the tours are
    those of every other plan, and the loop runs a few steps past ``n - 1`` when ants waited.
    """
    n = weights.shape[1]
    m = row_offset.shape[0]
    every = jnp.arange(m, dtype=jnp.int32)
    cands, cand_w, bk_node, bk_pos = _candidate_tables(weights, candidates, factor, backup)
    slots = max(1, min(m, m // div))
    rows_slots = max(1, min(slots, slots // div))

    def best_allowed(ants: Array, current: Array, bits: Array) -> Array:
        return _whole_row_best(weights, row_offset, factor, ants, current,
                               _unpack_bits(bits[ants], n))

    def step(carry):
        current, bits, pos, path = carry
        active = pos < n
        u = uniforms[jnp.clip(pos - 1, 0, n - 2), every]  # the draw of this tour position
        row = row_offset + current
        cand = cands[row]
        w = jnp.where(_test_bits(bits, every, cand), cand_w[row], 0.0)  # (m, k)
        w = w if factor is None else w * jnp.take_along_axis(factor, cand, axis=1)
        c, ok = _sample(w, u, q0)
        nxt = jnp.take_along_axis(cand, c[:, None], axis=1)[:, 0]
        ants = _compact(active & ~ok, slots, m)  # m: an empty slot
        real = ants < m
        a = jnp.minimum(ants, m - 1)
        if bk_node is not None:
            bk = bk_node[row[a]]
            valid = _test_bits(bits, a, bk) & bk_pos[row[a]]
            found = jnp.any(valid, axis=1)
            best = jnp.take_along_axis(bk, jnp.argmax(valid, axis=1)[:, None], axis=1)[:, 0]
            left = real & ~found
        else:
            best, left = jnp.zeros_like(a), real
        sub = _compact(left, rows_slots, slots)
        s = jnp.minimum(sub, slots - 1)
        best = best.at[sub].set(best_allowed(a[s], current[a[s]], bits), mode="drop")
        served = (real & ~left) | jnp.zeros(slots, bool).at[sub].set(True, mode="drop")
        nxt = nxt.at[ants].set(best, mode="drop")
        move = active & (ok | jnp.zeros(m, bool).at[ants].set(served, mode="drop"))
        nxt = jnp.where(move, nxt, current)
        word = bits[every, nxt >> 5]
        clear = jnp.where(move, ~(jnp.uint32(1) << (nxt & 31).astype(jnp.uint32)),
                          jnp.uint32(0xFFFFFFFF))
        bits = bits.at[every, nxt >> 5].set(word & clear, unique_indices=True)
        path = path.at[every, jnp.where(move, pos, n)].set(nxt, mode="drop")
        return nxt, bits, pos + move.astype(jnp.int32), path

    return step


def _step(weights: Array, row_offset: Array, q0: Array, factor: Array | None,
          candidates: Array | None, lazy: bool = True, backup: int = 0,
          fallback_ants: int = FALLBACK_ANTS):
    n = weights.shape[1]
    m = row_offset.shape[0]
    ant_base = (jnp.arange(m, dtype=jnp.int32) * n)[:, None]

    def best_allowed(ants: Array, current: Array, alive: Array) -> Array:
        return _whole_row_best(weights, row_offset, factor, ants, current, alive)

    every = jnp.arange(m, dtype=jnp.int32)
    if candidates is None:
        def step(carry, u):
            current, alive = carry
            w = jnp.where(alive, weights[row_offset + current], 0.0)  # (m, n), tabu nodes 0
            nxt, ok = _sample(w if factor is None else w * factor, u, q0)
            nxt = jnp.where(ok, nxt, jnp.argmax(alive, axis=1).astype(jnp.int32))
            return (nxt, alive.at[every, nxt].set(False, unique_indices=True)), nxt

        return step

    cands, cand_w, bk_node, bk_pos = _candidate_tables(weights, candidates, factor, backup)
    few_ants = min(fallback_ants, m)

    def fallback(current: Array, alive: Array, nxt: Array, pending: Array) -> Array:
        """Ants ``pending`` take the allowed node of largest weight in their whole row
        (ACOTSP's rule): searched for at most ``few_ants`` compacted ants, or (lazily, on steps
        with more of them; always when not ``lazy``) for every ant."""
        def everyone():
            return jnp.where(pending, best_allowed(every, current, alive), nxt)

        if not lazy:
            return everyone()
        ants = jnp.nonzero(pending, size=few_ants, fill_value=0)[0]
        best = best_allowed(ants, current[ants], alive[ants])

        def few():
            return nxt.at[ants].set(jnp.where(pending[ants], best, nxt[ants]))

        return jax.lax.cond(jnp.sum(pending) <= few_ants, few, everyone)

    def step(carry, u):
        current, alive = carry
        row = row_offset + current
        cand = cands[row]
        w = jnp.where(alive.reshape(-1)[ant_base + cand], cand_w[row], 0.0)  # (m, k)
        w = w if factor is None else w * factor.reshape(-1)[ant_base + cand]
        c, ok = _sample(w, u, q0)
        nxt = jnp.take_along_axis(cand, c[:, None], axis=1)[:, 0]
        pending = ~ok
        if bk_node is not None:  # first allowed node of the backup list: the whole-row answer
            bk = bk_node[row]
            valid = alive.reshape(-1)[ant_base + bk] & bk_pos[row]
            first = jnp.argmax(valid, axis=1)
            found = jnp.any(valid, axis=1)
            nxt = jnp.where(pending & found,
                            jnp.take_along_axis(bk, first[:, None], axis=1)[:, 0], nxt)
            pending = pending & ~found
        if lazy:
            nxt = jax.lax.cond(jnp.any(pending),
                               lambda: fallback(current, alive, nxt, pending), lambda: nxt)
        else:
            nxt = fallback(current, alive, nxt, pending)
        return (nxt, alive.at[every, nxt].set(False, unique_indices=True)), nxt

    return step


def construct_tours(
    key: Array,
    weights: Array,
    starts: Array,
    q0: Array | float = 0.0,
    row_offset: Array | None = None,
    factor: Array | None = None,
    candidates: Array | None = None,
    fallback: str = "auto",
) -> Array:
    """Build one tour per ant.

    Args:
      key: PRNG key; one draw with it gives every step its own row of uniforms.
      weights: (R, n) non-negative choice weights (from :func:`choice_weights`); an ant at node
        i reads row ``row_offset[k] + i`` (R = n normally; stacking matrices lets some ants, e.g.
        the pheromone-greedy ant of Eq. 6, use different weights in the same scan).
      starts: (m,) int start node per ant.
      q0: probability of the greedy choice, scalar or (m,) per ant (1 = fully greedy).
      factor: optional (m, n) multiplicative perturbation of the weights (chaos).
      candidates: optional (n, k) candidate lists (nearest neighbours). With them Eq. 2 and
        the q0 rule act on the k candidates that are not tabu, and an ant whose candidates are
        all tabu moves to the allowed node of largest weight (as ACOTSP does); the cost of a
        step drops from O(m n) sampling to O(m k). Without them Eq. 2 runs over all n nodes.
      fallback: how that whole-row search runs (static; every plan builds the same tours):
        "auto" (the backend's row of :data:`AUTO_PLANS`), "lazy"
        (a branch on steps where some ant needs it, compacting up to FALLBACK_ANTS ants),
        "dense" (every ant's whole row on every step), "backup" (a backup list of the BACKUP
        heaviest nodes per row first, then the lazy compacted search for up to m // 16 ants),
        "compact" (see :func:`_compact_step`), "kernel" (one Pallas kernel builds whole tours
        per block of ants, :mod:`eaco_jax.ops.construction_kernel`; needs candidate lists; a
        GPU runs it compiled, other backends in Pallas' interpreter, slowly; its prefix sums
        add in another order, see there).

    Returns:
      (m, n) int32 tours, each a permutation of 0..n-1 starting at ``starts``.
    """
    n = weights.shape[1]
    m = starts.shape[0]
    if weights.shape[0] % n:
        raise ValueError(f"weights must have a multiple of n={n} rows, got {weights.shape}")
    plans = {"lazy": (True, 0, FALLBACK_ANTS), "dense": (False, 0, m),
             "backup": (True, min(BACKUP, n - 1), max(8, m // 16))}
    if fallback == "auto":
        fallback = auto_plan()
        if fallback == "kernel" and candidates is None:
            fallback = "dense"  # the kernel needs candidate lists
    if fallback == "kernel":
        if candidates is None:
            raise ValueError('fallback="kernel" needs candidate lists (candidates=...)')
        plan = "kernel"
    elif fallback == "compact" and candidates is not None:
        plan = None
    elif fallback == "compact":
        plan = plans["dense"]  # without candidate lists every step searches whole rows
    elif fallback in plans:
        plan = plans[fallback]
    else:
        raise ValueError(f"fallback={fallback!r} is not one of auto, {', '.join(plans)}, "
                         "compact, kernel")
    starts = starts.astype(jnp.int32)
    if row_offset is None:
        row_offset = jnp.zeros((m,), jnp.int32)
    q0 = jnp.broadcast_to(jnp.asarray(q0, jnp.float32), (m,))
    alive = jnp.arange(n)[None, :] != starts[:, None]  # bool: 1 byte per entry
    uniforms = jax.random.uniform(key, (max(n - 1, 1), m))[: n - 1]
    if plan == "kernel":
        from eaco_jax.ops import construction_kernel

        cands = jnp.asarray(candidates, jnp.int32)
        backup = min(BACKUP, n - 1)
        cands, cand_w, bk_node, bk_ok = _candidate_tables(weights, cands, factor, backup)
        return construction_kernel.construct_tours_kernel(
            uniforms, weights, starts, q0, row_offset, factor, cands, cand_w, bk_node, bk_ok,
            _pack_bits(alive), backup=0 if bk_node is None else backup,
            interpret=not kernel_compiles_here(), block=construction_kernel.BLOCK)
    if plan is None:
        step = _compact_step(weights, row_offset.astype(jnp.int32), q0, factor,
                             jnp.asarray(candidates, jnp.int32), uniforms,
                             min(BACKUP, n - 1), COMPACT_DIV)
        path = jnp.zeros((m, n), jnp.int32).at[:, 0].set(starts)
        carry = (starts, _pack_bits(alive), jnp.ones((m,), jnp.int32), path)
        # n - 1 steps of known count (no host sync on a GPU), then the steps of ants that
        # waited for a slot, if any
        carry = jax.lax.fori_loop(0, n - 1, lambda _, c: step(c), carry, unroll=UNROLL)
        carry = jax.lax.while_loop(lambda c: jnp.any(c[2] < n), step, carry)
        return carry[3]
    step = _step(weights, row_offset.astype(jnp.int32), q0, factor, candidates, *plan)
    _, path = jax.lax.scan(step, (starts, alive), uniforms, unroll=UNROLL)
    return jnp.concatenate([starts[:, None], path.T], axis=1)


def tour_lengths(dist: Array, tours: Array) -> Array:
    """(m,) closed-tour lengths sum d[t_i, t_{i+1}] (float32; exact for integer TSPLIB d)."""
    nxt = jnp.roll(tours, -1, axis=1)
    return jnp.sum(dist[tours, nxt], axis=1)


def greedy_tour(weights: Array, start: Array | int = 0) -> Array:
    """The deterministic tour that always takes the largest-weight allowed edge (q0 = 1)."""
    starts = jnp.asarray([start], jnp.int32)
    return construct_tours(jax.random.key(0), weights, starts, q0=1.0)[0]
