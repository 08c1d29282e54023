"""Pheromone rules of the EACO colony: small pure functions over the (n, n) trail matrix.

In the optax spirit each rule does one thing and the strategy composes them; every rule has a
switch in :class:`eaco_jax.strategies.graph_eaco.GraphParams`, so an ablation is a config.

Units. Eq. 71 deposits 1/L on the global-best tour, so pheromone lives in units of 1/length.
The other rules deposit Q/L; with our default Q = 1 all rules share those units (the paper's
Table 4 Q = 100 is expressible). The paper writes Eq. 73 with a *persistence* rho
(tau <- rho tau + ...); we write every rule with an *evaporation rate* rho in (0, 1) and scale
deposits by rho (tau <- (1 - rho) tau + rho * deposit), so a tour reinforced every iteration
converges to its deposit and the MAX-MIN bound tau_max has the same meaning for every rule.

Rules:
  local_update         Eq. 68-70  on every edge an ant used: tau <- (1-rho) tau + rho sum_k Q/L_k
  global_update        Eq. 71     tau <- (1-alpha_g) tau + alpha_g [e in T_gb] / L_gb
  elitist_update       Eq. 73-74  tau <- (1-rho) tau + rho (sum_k w_k Q/L_k + sigma Q/L_best)
  elitist_deposit_mask Eq. 3-4    which ants may deposit
  adaptive_weight      Eq. 5      rho_n = L_n^-1 / (L_n^-1 + L_pn^-1)
  mmas_bounds / clamp  Eq. 7      tau in [tau_min, tau_max] (MAX-MIN Ant System)
  initial_tau                     tau0 = 1 / (n L_nn) (Table 4 footnote)
  evaporation_schedule            evaporation slowed as the colony stagnates

Sparse trails: with ``candidates`` (n, k) every rule acts on an (n, k) trail array, entry
(i, j) the edge from i to its j-th candidate (an edge in both of its cities' lists holds the
same value in both entries, as the dense matrix's two triangles do); edges outside the
candidate lists hold no trail, as in Focused ACO: construction never weighs them (its
fallback follows a reference tour).
With lists of every other city the (n, k) entries equal the dense matrix's, bit for bit.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def candidate_slots(a: Array, b: Array, candidates: Array) -> Array:
    """Index of ``b`` in the candidate list of ``a`` (elementwise), k where it is absent."""
    eq = candidates[a] == b[..., None]
    k = candidates.shape[1]
    return jnp.where(jnp.any(eq, axis=-1), jnp.argmax(eq, axis=-1), k).astype(jnp.int32)


def edge_sum(tours: Array, amounts: Array, n: int, candidates: Array | None = None) -> Array:
    """(n, n) symmetric matrix: sum over tours k of ``amounts[k]`` on each edge of tour k;
    with ``candidates`` the (n, k) entries of the candidate edges (others dropped), summed in
    the dense matrix's order (the forward uses, then the backward ones)."""
    nxt = jnp.roll(tours, -1, axis=1)
    a = jnp.broadcast_to(amounts[:, None], tours.shape).astype(jnp.float32)
    if candidates is not None:
        k = candidates.shape[1]
        flat = (n * k + 1,)  # the last entry collects edges outside the lists
        fwd_slot = candidate_slots(tours, nxt, candidates)
        bwd_slot = candidate_slots(nxt, tours, candidates)
        fwd_i = jnp.where(fwd_slot < k, tours * k + fwd_slot, n * k)
        bwd_i = jnp.where(bwd_slot < k, nxt * k + bwd_slot, n * k)
        fwd = jnp.zeros(flat, jnp.float32).at[fwd_i].add(a)[: n * k]
        bwd = jnp.zeros(flat, jnp.float32).at[bwd_i].add(a)[: n * k]
        return (fwd + bwd).reshape(n, k)
    m = jnp.zeros((n, n), jnp.float32).at[tours, nxt].add(a)
    return m + m.T


def edge_mask(tours: Array, n: int, candidates: Array | None = None) -> Array:
    """(n, n) bool (or (n, k) on ``candidates``): edges (either direction) used by at least
    one tour."""
    return edge_sum(tours, jnp.ones(tours.shape[0], jnp.float32), n, candidates) > 0


def initial_tau(n: int, nn_length: Array) -> Array:
    """tau0 = 1 / (n L_nn), L_nn the nearest-neighbour tour length (Table 4 footnote)."""
    return 1.0 / (n * jnp.asarray(nn_length, jnp.float32))


def local_update(tau: Array, tours: Array, lengths: Array, rho: Array, q: Array,
                 candidates: Array | None = None) -> Array:
    """Eq. 68-70: tau_ij <- (1-rho) tau_ij + rho sum_k Q/L_k on the edges the ants used."""
    n = tau.shape[0]
    delta = edge_sum(tours, q / lengths, n, candidates)
    used = edge_mask(tours, n, candidates)
    return jnp.where(used, (1.0 - rho) * tau + rho * delta, tau)


def global_update(tau: Array, best_tour: Array, best_length: Array, alpha_g: Array,
                  candidates: Array | None = None) -> Array:
    """Eq. 71: tau <- (1-alpha_g) tau + alpha_g Delta, Delta = 1/L_gb on global-best edges."""
    n = tau.shape[0]
    delta = edge_sum(best_tour[None], (1.0 / best_length)[None], n, candidates)
    return (1.0 - alpha_g) * tau + alpha_g * delta


def elitist_update(
    tau: Array,
    tours: Array,
    lengths: Array,
    deposit_weights: Array,
    best_tour: Array,
    best_length: Array,
    rho: Array,
    q: Array,
    sigma: Array,
    candidates: Array | None = None,
) -> Array:
    """Eq. 73-74: evaporate, every ant k deposits w_k Q/L_k, the best tour gets sigma Q/L_best.

    ``deposit_weights`` (m,) selects and weights the depositing ants (Eq. 3-4 mask times the
    Eq. 5 adaptive weight, or all zeros for best-tour-only reinforcement); ``sigma`` is the
    number of elitist ants.
    """
    n = tau.shape[0]
    colony = edge_sum(tours, deposit_weights * q / lengths, n, candidates)
    elite = edge_sum(best_tour[None], (sigma * q / best_length)[None], n, candidates)
    return (1.0 - rho) * tau + rho * (colony + elite)


def elitist_deposit_mask(lengths: Array, previous_min: Array) -> Array:
    """Eq. 3-4: ants may deposit only if d_min(t) < d_min(t-1) and their length < d_aver(t)."""
    improved = jnp.min(lengths) < previous_min
    return improved & (lengths < jnp.mean(lengths))


def adaptive_weight(length: Array, pheromone_tour_length: Array) -> Array:
    """Eq. 5: rho_n = L_n^-1 / (L_n^-1 + L_pn^-1) in (0, 1); 1/2 when L_n equals L_pn."""
    a = 1.0 / length
    return a / (a + 1.0 / pheromone_tour_length)


def mmas_bounds(
    best_length: Array, n: int, p_best: Array, scale: Array = 1.0, avg: Array | float = 0.0
) -> tuple[Array, Array]:
    """MAX-MIN limits: tau_max = scale / L_best (the steady state of a tour reinforced every
    iteration in our units), tau_min = tau_max (1 - p^(1/n)) / (avg p^(1/n)) (Stuetzle &
    Hoos 2000: with tau at its limits the best tour is rebuilt with probability p_best).

    ``avg`` is the average number of choices an ant has per step: n/2 - 1 when it is <= 0
    (the default), or about half the candidate list on candidate lists (ACOTSP's
    (nn_ants + 1) / 2)."""
    tau_max = scale / best_length
    root = p_best ** (1.0 / n)
    avg = jnp.where(jnp.asarray(avg) > 0, avg, max(n / 2.0 - 1.0, 1.0))
    tau_min = tau_max * (1.0 - root) / (avg * root)
    return tau_max.astype(jnp.float32), jnp.minimum(tau_min, tau_max).astype(jnp.float32)


def clamp(tau: Array, tau_min: Array, tau_max: Array) -> Array:
    """Eq. 7: clip every trail into [tau_min, tau_max]."""
    return jnp.clip(tau, tau_min, tau_max)


def evaporation_schedule(rho: Array, stagnation: Array, window: Array, strength: Array) -> Array:
    """Evaporation rate slowed as the best-so-far stagnates (more persistence, wider search):
    rho_t = rho (1 - strength * min(stagnation / window, 1)). strength = 0 keeps rho fixed."""
    level = jnp.clip(stagnation / jnp.maximum(window, 1.0), 0.0, 1.0)
    return rho * (1.0 - strength * level)


def reset(tau: Array, value: Array, do_reset: Array) -> Array:
    """MMAS restart: every trail back to ``value`` where ``do_reset`` is true."""
    return jnp.where(do_reset, jnp.full_like(tau, value), tau)


def branching_factor(tau: Array, candidates: Array | None, lam: float = 0.05) -> Array:
    """Average lambda-branching factor of the trails on the candidate lists, normalised so a
    converged colony (two strong edges per node) scores 1 (Dorigo & Stuetzle 2004; ACOTSP):
    per node, the candidates whose trail exceeds min + lam (max - min), over 2n.
    ``candidates=None``: ``tau`` holds the candidate edges' trails already (n, k)."""
    t = tau if candidates is None else jnp.take_along_axis(tau, candidates, axis=1)
    lo, hi = jnp.min(t, axis=1, keepdims=True), jnp.max(t, axis=1, keepdims=True)
    count = jnp.sum(t > lo + lam * (hi - lo), dtype=jnp.int32)
    return (count / (2.0 * tau.shape[0])).astype(jnp.float32)


def candidate_edge_diversity(tours: Array, candidates: Array) -> Array:
    """:func:`eaco_jax.ops.diversity.edge_diversity` in O(m n k) time and O(n k) memory:
    edges are counted on the candidate lists (an edge outside both of its cities' lists
    counts as shared by no other tour)."""
    tours = jnp.asarray(tours, jnp.int32)
    m, n = tours.shape
    if m < 2 or n < 3:
        return jnp.zeros((), jnp.float32)
    k = candidates.shape[1]
    nxt = jnp.roll(tours, -1, axis=1)
    lo, hi = jnp.minimum(tours, nxt), jnp.maximum(tours, nxt)
    s_lo, s_hi = candidate_slots(lo, hi, candidates), candidate_slots(hi, lo, candidates)
    edge = jnp.where(s_lo < k, lo * k + s_lo, jnp.where(s_hi < k, hi * k + s_hi, n * k))
    count = jnp.zeros((n * k + 1,), jnp.float32).at[edge.reshape(-1)].add(1.0)[: n * k]
    shared = jnp.sum(count * (count - 1.0))
    pairs = jnp.float32(n * m * (m - 1))
    return jnp.clip((pairs - shared) / pairs, 0.0, 1.0).astype(jnp.float32)
