"""Precision rules: when :func:`~eaco_jax.driver.minimize.minimize` runs a problem in float64,
and the problem's arrays converted to it."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ConfigError

PRECISIONS = ("auto", "float32", "float64")


def float_leaves(tree: Any) -> list[Any]:
    return [x for x in jax.tree.leaves(tree)
            if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating)]


def needs_float64(problem: Any, precision: str = "auto") -> bool:
    """Whether :func:`minimize` runs ``problem`` in float64 (see the README's rule).

    ``auto``: float64 for a problem that holds float64 arrays (built inside
    :func:`eaco_jax.problems.float64`) or has constraints (inequality or equality) and is
    differentiable JAX code; otherwise the problem's own dtype. ``float32`` with a float64
    problem is refused (one line).
    """
    if precision not in PRECISIONS:
        raise ConfigError(f"precision={precision!r} is not one of {', '.join(PRECISIONS)}")
    has64 = any(x.dtype == np.float64 for x in float_leaves(problem))
    if precision == "float64":
        return True
    if precision == "float32":
        if has64:
            raise ConfigError(
                f"problem {getattr(problem, 'name', '')!r} holds float64 arrays (built inside "
                "float64()); use precision='float64' or 'auto', or build it outside float64()")
        return False
    constrained = (int(getattr(problem, "num_inequality", 0))
                   + int(getattr(problem, "num_equality", 0))) > 0
    return has64 or (constrained and bool(getattr(problem, "differentiable", True)))


def as_float64(problem: Any) -> Any:
    """``problem`` with its floating-point arrays in float64 (call inside a float64 scope)."""
    return jax.tree.map(
        lambda x: jnp.asarray(x, jnp.float64)
        if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating) else x, problem)
