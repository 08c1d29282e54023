"""Pieces the graph baselines (ant system, ACS, annealing and tabu on tours) share.

Construction and 2-opt are the library's (:mod:`eaco_jax.ops.construction`,
:mod:`eaco_jax.ops.local_search`), the same code GraphEACO runs, so a comparison between
colonies differs only in the pheromone rules.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.ops.construction import (
    choice_weights,
    construct_tours,
    heuristic_log_eta,
    tour_lengths,
)

Array = jax.Array

LOCAL_SEARCHES = ("2opt", "none")


def check_graph(strategy: Any, problem: Any) -> Any:
    """``problem`` if it has an (n, n) distance matrix with n >= 3, else a ProblemError."""
    shape = getattr(getattr(problem, "dist", None), "shape", ())
    if len(shape) != 2 or shape[0] != shape[1] or shape[0] < 3:
        raise ProblemError(
            f"{type(strategy).__name__} needs an (n, n) distance matrix, n >= 3; got {shape}")
    return problem


def check_local_search(local_search: str) -> None:
    if local_search not in LOCAL_SEARCHES:
        raise ConfigError(f"local_search={local_search!r} is not one of {LOCAL_SEARCHES}")


def nearest_neighbour_length(problem: Any) -> Array:
    """Length of the nearest-neighbour tour from city 0 (L_nn of the tau0 formulas)."""
    dist = jnp.asarray(problem.dist, jnp.float32)
    w = choice_weights(jnp.ones_like(dist), heuristic_log_eta(dist), 0.0, 1.0)
    tour = construct_tours(jax.random.key(0), w, jnp.zeros((1,), jnp.int32), q0=1.0)
    return tour_lengths(dist, tour)[0]


def build(key: Array, tau: Array, problem: Any, num_ants: int, alpha: Array, beta: Array,
          q0: Array | float = 0.0, candidate_lists: bool = True) -> Array:
    """``num_ants`` tours by Eq. 2 (and the q0 rule) from random start cities."""
    dist = jnp.asarray(problem.dist, jnp.float32)
    n = dist.shape[0]
    k_start, k_build = jax.random.split(key)
    weights = choice_weights(tau, heuristic_log_eta(dist), alpha, beta)
    starts = jax.random.randint(k_start, (num_ants,), 0, n, jnp.int32)
    cands = problem.neighbors if candidate_lists else None
    return construct_tours(k_build, weights, starts, q0, candidates=cands)


def improve(tours: Array, problem: Any, local_search: str) -> Array:
    """2-opt on the candidate lists, or the tours unchanged."""
    if local_search == "none":
        return tours
    from eaco_jax.ops.local_search import two_opt

    return two_opt(tours, jnp.asarray(problem.dist, jnp.float32), problem.neighbors)


def random_tours(key: Array, m: int, n: int) -> Array:
    """``(m, n)`` uniform random permutations."""
    keys = jax.random.split(key, m)
    return jax.vmap(lambda k: jax.random.permutation(k, n))(keys).astype(jnp.int32)


NEIGHBOURHOODS = ("2opt", "swap")


def check_neighbourhood(neighbourhood: str) -> None:
    if neighbourhood not in NEIGHBOURHOODS:
        raise ConfigError(f"neighbourhood={neighbourhood!r} is not one of {NEIGHBOURHOODS}")


def random_move(key: Array, tour: Array, neighbourhood: str) -> Array:
    """One random neighbour of ``tour``: a 2-opt move (reverse positions i..j, i < j) or a
    swap of the cities at two distinct positions."""
    n = tour.shape[0]
    k1, k2 = jax.random.split(key)
    i = jax.random.randint(k1, (), 0, n)
    j = (i + jax.random.randint(k2, (), 1, n)) % n  # j != i
    lo, hi = jnp.minimum(i, j), jnp.maximum(i, j)
    pos = jnp.arange(n)
    if neighbourhood == "swap":
        src = jnp.where(pos == lo, hi, jnp.where(pos == hi, lo, pos))
    else:
        src = jnp.where((pos >= lo) & (pos <= hi), lo + hi - pos, pos)
    return tour[src]
