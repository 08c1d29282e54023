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
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array


def edge_sum(tours: Array, amounts: Array, n: int) -> Array:
    """(n, n) symmetric matrix: sum over tours k of ``amounts[k]`` on each edge of tour k."""
    nxt = jnp.roll(tours, -1, axis=1)
    a = jnp.broadcast_to(amounts[:, None], tours.shape).astype(jnp.float32)
    m = jnp.zeros((n, n), jnp.float32).at[tours, nxt].add(a)
    return m + m.T


def edge_mask(tours: Array, n: int) -> Array:
    """(n, n) bool: edges (either direction) used by at least one tour."""
    return edge_sum(tours, jnp.ones(tours.shape[0], jnp.float32), n) > 0


def initial_tau(n: int, nn_length: Array) -> Array:
    """tau0 = 1 / (n L_nn), L_nn the nearest-neighbour tour length (Table 4 footnote)."""
    return 1.0 / (n * jnp.asarray(nn_length, jnp.float32))


def local_update(tau: Array, tours: Array, lengths: Array, rho: Array, q: Array) -> Array:
    """Eq. 68-70: tau_ij <- (1-rho) tau_ij + rho sum_k Q/L_k on the edges the ants used."""
    n = tau.shape[0]
    delta = edge_sum(tours, q / lengths, n)
    used = edge_mask(tours, n)
    return jnp.where(used, (1.0 - rho) * tau + rho * delta, tau)


def global_update(tau: Array, best_tour: Array, best_length: Array, alpha_g: Array) -> Array:
    """Eq. 71: tau <- (1-alpha_g) tau + alpha_g Delta, Delta = 1/L_gb on global-best edges."""
    n = tau.shape[0]
    delta = edge_sum(best_tour[None], (1.0 / best_length)[None], n)
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
) -> Array:
    """Eq. 73-74: evaporate, every ant k deposits w_k Q/L_k, the best tour gets sigma Q/L_best.

    ``deposit_weights`` (m,) selects and weights the depositing ants (Eq. 3-4 mask times the
    Eq. 5 adaptive weight, or all zeros for best-tour-only reinforcement); ``sigma`` is the
    number of elitist ants.
    """
    n = tau.shape[0]
    colony = edge_sum(tours, deposit_weights * q / lengths, n)
    elite = edge_sum(best_tour[None], (sigma * q / best_length)[None], n)
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


def branching_factor(tau: Array, candidates: Array, lam: float = 0.05) -> Array:
    """Average lambda-branching factor of the trails on the candidate lists, normalised so a
    converged colony (two strong edges per node) scores 1 (Dorigo & Stuetzle 2004; ACOTSP):
    per node, the candidates whose trail exceeds min + lam (max - min), over 2n."""
    t = jnp.take_along_axis(tau, candidates, axis=1)
    lo, hi = jnp.min(t, axis=1, keepdims=True), jnp.max(t, axis=1, keepdims=True)
    count = jnp.sum(t > lo + lam * (hi - lo), dtype=jnp.int32)
    return (count / (2.0 * tau.shape[0])).astype(jnp.float32)
