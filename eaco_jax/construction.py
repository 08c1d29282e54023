"""Tour construction on a construction graph: the whole colony in one ``lax.scan``.

Each ant starts at a node and adds one node per step. At node i with tabu set (visited nodes)
T_k it chooses the next node j

* greedily, j = argmax_{u not in T_k} tau_iu^alpha eta_iu^beta, with probability q0
  (the pseudo-random proportional rule of ACS, Table 3's ``q0``), otherwise
* at random with p_ij proportional to tau_ij^alpha eta_ij^beta over j not in T_k (Eq. 2).

The choice weights may be multiplied by a per-ant chaos factor (see :mod:`eaco_jax.chaos`).
All ants move together: one scan step is a batched gather of the current rows of the weight
matrix (or of the k candidate columns, see ``candidates``), a tabu mask, a cumulative sum and
one uniform draw per ant (inverse-CDF sampling); there is no Python loop over ants or steps.
Every step gets its own PRNG key, split from the caller's key; the uniforms of all steps are
drawn in one batched call before the scan (XLA:CPU pays a fixed cost per operation inside a
loop, so fewer, larger operations are faster).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array
#: construction steps per loop iteration of the compiled scan (fewer loop round-trips on CPU)
UNROLL = 2


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


def _step(
    weights: Array,
    row_offset: Array,
    q0: Array,
    factor: Array | None,
    candidates: Array | None,
):
    n = weights.shape[1]
    nodes = jnp.arange(n, dtype=jnp.int32)
    id_bits = max(1, (n - 1).bit_length())
    value_scale = float((1 << (31 - id_bits)) - 1)
    if candidates is not None:
        # choice weights of each row's candidates, gathered once per construction: (R, k)
        cand_rows = jnp.concatenate([candidates] * (weights.shape[0] // n), axis=0)
        cand_w = jnp.take_along_axis(weights, cand_rows, axis=1)

    def pick(w: Array, u: Array) -> tuple[Array, Array, Array]:
        """Greedy index, Eq. 2 sample (inverse CDF), and whether any weight is positive."""
        greedy = jnp.argmax(w, axis=1)
        cum = jnp.cumsum(w, axis=1)
        total = cum[:, -1]
        above = cum > (u[0] * total)[:, None]
        sampled = jnp.where(jnp.any(above, axis=1), jnp.argmax(above, axis=1), greedy)
        chosen = jnp.where(u[1] < q0, greedy, sampled)
        return chosen, total > 0, greedy

    def full_row(current: Array, visited: Array, u: Array) -> Array:
        w = weights[row_offset + current]  # (m, n)
        if factor is not None:
            w = w * factor
        w = jnp.where(visited, -1.0, w)
        chosen, ok, _ = pick(jnp.maximum(w, 0.0), u)
        # all allowed weights zero (underflow): best allowed node by weight, never a tabu one
        return jnp.where(ok, chosen, jnp.argmax(w, axis=1))

    def best_allowed(current: Array, visited: Array) -> Array:
        """argmax of the allowed weights as ONE int32 max: weight quantised to the high bits,
        node id in the low bits (XLA:CPU's variadic argmax reduce is several times slower)."""
        w = weights[row_offset + current]
        if factor is not None:
            w = w * factor
        w = w if factor is None else w * 0.5  # chaos factors are <= 2
        q = (jnp.clip(w, 0.0, 1.0) * value_scale).astype(jnp.int32)  # rows scaled to max 1
        packed = jnp.where(visited, -1, q * (1 << id_bits) + nodes[None, :])
        return jnp.max(packed, axis=1) & ((1 << id_bits) - 1)

    def step(carry, u):
        current, visited = carry
        if candidates is None:
            nxt = full_row(current, visited, u)
        else:
            row = row_offset + current
            cand = cand_rows[row]  # (m, k)
            w = cand_w[row]
            if factor is not None:
                w = w * jnp.take_along_axis(factor, cand, axis=1)
            w = jnp.where(jnp.take_along_axis(visited, cand, axis=1), 0.0, w)
            chosen, ok, _ = pick(w, u)
            nxt_c = jnp.take_along_axis(cand, chosen[:, None], axis=1)[:, 0]
            # all candidates tabu: the best allowed node over the whole row (ACOTSP's rule)
            nxt = jnp.where(ok, nxt_c, best_allowed(current, visited))
        nxt = nxt.astype(jnp.int32)
        visited = visited | (nodes[None, :] == nxt[:, None])
        return (nxt, visited), nxt

    return step


def construct_tours(
    key: Array,
    weights: Array,
    starts: Array,
    q0: Array | float = 0.0,
    row_offset: Array | None = None,
    factor: Array | None = None,
    candidates: Array | None = None,
) -> Array:
    """Build one tour per ant.

    Args:
      key: PRNG key; one subkey per construction step is split from it.
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

    Returns:
      (m, n) int32 tours, each a permutation of 0..n-1 starting at ``starts``.
    """
    n = weights.shape[1]
    m = starts.shape[0]
    if weights.shape[0] % n:
        raise ValueError(f"weights must have a multiple of n={n} rows, got {weights.shape}")
    starts = starts.astype(jnp.int32)
    if row_offset is None:
        row_offset = jnp.zeros((m,), jnp.int32)
    q0 = jnp.broadcast_to(jnp.asarray(q0, jnp.float32), (m,))
    visited = jnp.arange(n)[None, :] == starts[:, None]
    # one key per step, all steps' uniforms drawn in one batched call before the scan
    keys = jax.random.split(key, max(n - 1, 1))[: n - 1]
    uniforms = jax.vmap(lambda k: jax.random.uniform(k, (2, m)))(keys)
    step = _step(weights, row_offset.astype(jnp.int32), q0, factor, candidates)
    _, path = jax.lax.scan(step, (starts, visited), uniforms, unroll=UNROLL)
    return jnp.concatenate([starts[:, None], path.T], axis=1)


def tour_lengths(dist: Array, tours: Array) -> Array:
    """(m,) closed-tour lengths sum d[t_i, t_{i+1}] (float32; exact for integer TSPLIB d)."""
    nxt = jnp.roll(tours, -1, axis=1)
    return jnp.sum(dist[tours, nxt], axis=1)


def greedy_tour(weights: Array, start: Array | int = 0) -> Array:
    """The deterministic tour that always takes the largest-weight allowed edge (q0 = 1)."""
    starts = jnp.asarray([start], jnp.int32)
    return construct_tours(jax.random.key(0), weights, starts, q0=1.0)[0]
