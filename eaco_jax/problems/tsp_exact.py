"""Exact integer tour lengths inside a run (no 64-bit integers: JAX runs without x64) and the
tour check, shared by the dense and the sparse TSP."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.problems.base import ProblemError

#: integer tour lengths below this are summed in one int32 word inside a run; a matrix whose
#: tours can reach it is summed in two (:func:`exact_int_sum`)
INT32_SUM_LIMIT = 2**31 - 1
#: :func:`exact_int_sum` holds the sums of n 12-bit halves in int32: at most this many cities
WIDE_SUM_MAX_CITIES = (2**31 - 1) // 4095


def exact_int_sum(edges: jax.Array) -> jax.Array:
    """float32 of the exact sum over the last axis of int32 ``edges`` (each in [0, 2**24)).

    Each edge splits at bit 12 into a high and a low half; both halves sum exactly in int32
    (fewer than :data:`WIDE_SUM_MAX_CITIES` terms), the low sum's carry moves to the high sum,
    and ``high * 4096 + low`` rounds once to float32. Exact to 2**36 before that rounding, and
    monotone beyond (the low part is then below half a float32 step), so two tours never
    compare in the wrong order; two int32 sums instead of one, with no 64-bit integers (JAX
    runs without x64 here).
    """
    hi = jnp.sum(edges >> 12, axis=-1, dtype=jnp.int32)
    lo = jnp.sum(edges & 4095, axis=-1, dtype=jnp.int32)
    hi = hi + (lo >> 12)
    return hi.astype(jnp.float32) * 4096.0 + (lo & 4095).astype(jnp.float32)


def words_needed(longest: float, n: int) -> int:
    """int32 words an integer tour length needs inside a run: 1 while no tour can reach
    2**31 (``longest`` bounds every tour), else 2; refuses more cities than 2 words hold."""
    if longest <= INT32_SUM_LIMIT:
        return 1
    if n > WIDE_SUM_MAX_CITIES:
        raise ProblemError(
            f"{n} cities of integer distances: tour lengths up to {longest:.0f} need more "
            f"than the {WIDE_SUM_MAX_CITIES:,} cities that two int32 words sum exactly; "
            "use at most that many cities")
    return 2


def integer_lengths(edges: jax.Array, words: int) -> jax.Array:
    """float32 tour lengths from int32 ``edges`` (..., n): one exact int32 sum (``words=1``,
    every tour below 2**31) or :func:`exact_int_sum`, each rounded once."""
    if words == 1:
        return edges.sum(-1).astype(jnp.float32)
    return exact_int_sum(edges)


def validate_tour(tour: np.ndarray, n: int) -> np.ndarray:
    """Check that ``tour`` is a permutation of ``0..n-1``; return it as int64, else raise."""
    t = np.asarray(tour)
    if t.shape != (n,):
        raise ProblemError(f"a tour must have shape ({n},), got {t.shape}")
    if not np.issubdtype(t.dtype, np.integer):
        if not np.all(np.isfinite(t)) or np.any(t != np.round(t)):
            raise ProblemError("a tour must hold integer city ids")
    t = t.astype(np.int64)
    if t.min() < 0 or t.max() >= n:
        raise ProblemError(f"tour has city ids outside 0..{n - 1}")
    counts = np.bincount(t, minlength=n)
    if np.any(counts != 1):
        missing = np.flatnonzero(counts == 0)[:5].tolist()
        twice = np.flatnonzero(counts > 1)[:5].tolist()
        raise ProblemError(f"tour is not a permutation: repeated {twice}, missing {missing}")
    return t


def host_lengths(problem: Any, tours: Any) -> np.ndarray:
    """Float64 lengths of concrete tours ``(m, n)`` from the host, each checked by the
    problem's ``exact_length`` (a wrong shape is one :class:`ProblemError`)."""
    t = np.asarray(tours)
    if t.ndim != 2 or t.shape[1] != problem.n:
        raise ProblemError(
            f"{problem.name}: evaluate takes tours of shape (m, {problem.n}), got {t.shape}")
    return np.array([problem.exact_length(row) for row in t], dtype=np.float64)
