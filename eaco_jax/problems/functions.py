"""Unconstrained test functions (sphere, Rosenbrock, Rastrigin, Ackley) as ConstrainedProblems.

Box-bounded, no constraints, minimum 0; used by tests and as a sanity check of the continuous
colony on problems whose difficulty is well known.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from eaco_jax.errors import ProblemError
from eaco_jax.problems.constrained import ConstrainedProblem

Array = jax.Array


def _sphere(x: Array) -> Array:
    return jnp.sum(x**2)


def _rosenbrock(x: Array) -> Array:
    return jnp.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1.0 - x[:-1]) ** 2)


def _rastrigin(x: Array) -> Array:
    return 10.0 * x.shape[0] + jnp.sum(x**2 - 10.0 * jnp.cos(2.0 * jnp.pi * x))


def _ackley(x: Array) -> Array:
    n = x.shape[0]
    a = -20.0 * jnp.exp(-0.2 * jnp.sqrt(jnp.sum(x**2) / n))
    b = -jnp.exp(jnp.sum(jnp.cos(2.0 * jnp.pi * x)) / n)
    return a + b + 20.0 + jnp.e


def sphere(dim: int = 10, bound: float = 5.12) -> ConstrainedProblem:
    """sum x_i^2 on [-bound, bound]^dim."""
    return ConstrainedProblem(_sphere, lower=[-bound] * dim, upper=[bound] * dim,
                              name=f"sphere{dim}", f_star=0.0)


def rosenbrock(dim: int = 10, bound: float = 5.0) -> ConstrainedProblem:
    """sum 100 (x_{i+1} - x_i^2)^2 + (1 - x_i)^2, minimum at (1, ..., 1)."""
    if dim < 2:
        raise ProblemError("rosenbrock needs dim >= 2")
    return ConstrainedProblem(_rosenbrock, lower=[-bound] * dim, upper=[bound] * dim,
                              name=f"rosenbrock{dim}", f_star=0.0)


def rastrigin(dim: int = 10, bound: float = 5.12) -> ConstrainedProblem:
    """10 n + sum x_i^2 - 10 cos(2 pi x_i): highly multimodal."""
    return ConstrainedProblem(_rastrigin, lower=[-bound] * dim, upper=[bound] * dim,
                              name=f"rastrigin{dim}", f_star=0.0)


def ackley(dim: int = 10, bound: float = 32.768) -> ConstrainedProblem:
    """Ackley's function, minimum 0 at the origin."""
    return ConstrainedProblem(_ackley, lower=[-bound] * dim, upper=[bound] * dim,
                              name=f"ackley{dim}", f_star=0.0)
