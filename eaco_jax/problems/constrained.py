"""Constrained continuous problems from plain JAX functions of one vector.

The user writes ``objective(x) -> scalar``, ``inequality(x) -> (p,)`` (feasible when every
entry is <= 0) and ``equality(x) -> (q,)`` (feasible when every |entry| <= 1e-4, the CEC2006
convention); the library vmaps them over the colony. The problem is a pytree (a ``flax.struct``
dataclass, as the other problems): the bounds are array leaves, the functions and the name are
static, so a jitted driver can take it as an argument.

Precision: the problem keeps the dtype of its bounds. Built while 64-bit mode is on
(``with jax.enable_x64(True):``, see :func:`float64`) everything - bounds, colony archive,
objective - is float64. That matters for a 1e-4 accuracy on objectives of magnitude 1e3
(g09 ~ 680, g10 ~ 7049: the float32 spacing at 7049 is 4.9e-4). float32 is the default.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Callable, Iterator
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.problems.base import Box, Evaluation, ProblemError

Array = jax.Array

#: equality constraints count as met when |h(x)| <= this (CEC2006 rule)
EQUALITY_TOLERANCE = 1e-4


@contextlib.contextmanager
def float64() -> Iterator[None]:
    """Run a block in JAX 64-bit mode (a scoped ``jax.enable_x64(True)``, never global).

    Build the problem *and* call ``minimize`` inside the block, e.g.::

        with float64():
            result = minimize(cec2006("g10"), max_evaluations=200_000)
    """
    with jax.enable_x64(True):
        yield


def _no_constraints(x: Array) -> Array:
    return jnp.zeros((0,), x.dtype)


@struct.dataclass(eq=False)
class ConstrainedProblem(Box):
    """Minimise ``objective(x)`` s.t. ``inequality(x) <= 0``, ``equality(x) == 0``, in a box.

    ``objective``, ``inequality`` and ``equality`` are plain JAX functions of ONE vector
    (returning a scalar, a ``(p,)`` and a ``(q,)`` array); ``None`` means no such constraints.
    Construction validates bounds (finite, same length, not reversed) and the functions' output
    shapes (abstractly, with ``jax.eval_shape``) and raises one :class:`ProblemError`.

    A ``flax.struct`` dataclass: ``lower`` and ``upper`` are leaves; functions, name and
    ``f_star`` (the known optimum, if any) are static. ``differentiable=False`` marks functions
    JAX cannot differentiate (a simulator behind a callback): strategies then take no gradient
    steps. ``num_inequality`` / ``num_equality`` are derived at construction (p and q); given,
    as unflattening and ``replace`` give them, the fields are taken as already checked.
    """

    objective: Callable[[Array], Array] = struct.field(pytree_node=False)
    inequality: Callable[[Array], Array] | None = struct.field(pytree_node=False, default=None)
    equality: Callable[[Array], Array] | None = struct.field(pytree_node=False, default=None)
    _: dataclasses.KW_ONLY
    lower: Array
    upper: Array
    name: str = struct.field(pytree_node=False, default="constrained")
    f_star: float | None = struct.field(pytree_node=False, default=None)
    differentiable: bool = struct.field(pytree_node=False, default=True)
    num_inequality: int = struct.field(pytree_node=False, default=-1)
    num_equality: int = struct.field(pytree_node=False, default=-1)

    kind: ClassVar[str] = "continuous"

    def __post_init__(self) -> None:
        if self.num_inequality >= 0 and self.num_equality >= 0:
            return  # unflattened or replaced: checked when it was built
        fields = _validated(self.objective, self.inequality, self.equality, self.lower,
                            self.upper, self.name, self.f_star)
        fields["differentiable"] = bool(self.differentiable)
        for key, value in fields.items():
            object.__setattr__(self, key, value)

    def __repr__(self) -> str:
        return (f"ConstrainedProblem(name={self.name!r}, dim={self.dim}, "
                f"inequality={self.num_inequality}, equality={self.num_equality}, "
                f"f_star={self.f_star})")

    # ------------------------------------------------------------------ single vector
    def constraints(self, x: Array) -> tuple[Array, Array]:
        """``(g(x), h(x))`` for one vector (shapes ``(p,)`` and ``(q,)``)."""
        return (
            jnp.asarray(self.inequality(x), x.dtype).reshape(self.num_inequality),
            jnp.asarray(self.equality(x), x.dtype).reshape(self.num_equality),
        )

    def violation_one(self, x: Array) -> Array:
        """Total violation of one vector: sum max(0, g) + sum max(0, |h| - 1e-4)."""
        g, h = self.constraints(x)
        return violation_of(g, h)

    def evaluate_one(self, x: Array) -> tuple[Array, Array]:
        """Objective and violation of one vector."""
        f = jnp.asarray(self.objective(x), x.dtype).reshape(())
        return f, self.violation_one(x)

    # ------------------------------------------------------------------ host check
    def host_check(self, x: Any) -> dict[str, Any]:
        """Objective and violation of one point, recomputed on the host in float64.

        What :func:`~eaco_jax.minimize` reports: ``f``, ``violation``, ``feasible`` (every
        ``g <= 0`` and every ``|h| <= 1e-4``: the tolerances, also returned; and a finite
        ``f``) and ``cost`` (``f`` if feasible, else +inf). A point outside the bounds raises
        :class:`ProblemError` (the driver turns that into a bug report).
        """
        point = np.asarray(x, np.float64).reshape(-1)
        lo, hi = np.asarray(self.lower, np.float64), np.asarray(self.upper, np.float64)
        if point.shape != lo.shape:
            raise ProblemError(f"problem {self.name!r}: a point must have shape {lo.shape}, "
                               f"got {point.shape}")
        # a float32 run clips to float32 bounds: allow their rounding
        slack = 4 * np.finfo(np.asarray(self.lower).dtype).eps * np.maximum(np.abs(lo), 1.0)
        if np.any(point < lo - slack) or np.any(point > hi + slack):
            raise ProblemError(f"problem {self.name!r}: point outside its bounds")
        with jax.enable_x64(True):
            p64 = self.replace(lower=jnp.asarray(lo), upper=jnp.asarray(hi))
            x64 = jnp.asarray(point, jnp.float64)
            f, v = p64.evaluate_one(x64)
            f, v = float(f), float(v)
        if math.isnan(v):
            v = math.inf
        feasible = v <= 0.0 and math.isfinite(f)  # an infinite or NaN f is no solution
        return {"f": f, "violation": v, "feasible": feasible,
                "cost": f if feasible else math.inf,
                "tolerance": {"inequality": 0.0, "equality": EQUALITY_TOLERANCE}}

    # ------------------------------------------------------------------ batched
    def evaluate(self, solutions: Array) -> Evaluation:
        """Objective and total violation of a batch ``(m, n)`` of vectors."""
        if not isinstance(solutions, jax.core.Tracer):
            shape = np.shape(solutions)
            if len(shape) != 2 or shape[1] != self.dim:
                raise ProblemError(f"problem {self.name!r}: evaluate takes points of shape "
                                   f"(m, {self.dim}), got {shape}")
        f, v = jax.vmap(self.evaluate_one)(solutions)
        return Evaluation(f=f, violation=v)


def violation_of(g: Array, h: Array) -> Array:
    """CEC2006 violation: inequality excess plus equality excess beyond the 1e-4 tolerance."""
    vg = jnp.sum(jnp.maximum(g, 0.0))
    vh = jnp.sum(jnp.maximum(jnp.abs(h) - EQUALITY_TOLERANCE, 0.0))
    return vg + vh


def _output_size(fn: Callable, x: jax.ShapeDtypeStruct, what: str, name: str) -> int:
    """Number of outputs of ``fn`` on one vector, checked abstractly with ``jax.eval_shape``."""
    try:
        out = jax.eval_shape(fn, x)
    except Exception as err:  # noqa: BLE001 - any failure in user code is a problem error
        raise ProblemError(
            f"problem {name!r}: the {what} function fails on a vector of shape {x.shape}: "
            f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"
        ) from None
    shape = getattr(out, "shape", None)
    if shape is None:
        raise ProblemError(f"problem {name!r}: the {what} function must return one array")
    if what == "objective":
        if shape not in ((), (1,)):
            raise ProblemError(
                f"problem {name!r}: the objective must return a scalar for one vector of shape "
                f"{x.shape}, got shape {shape}"
            )
        return 1
    if len(shape) != 1:
        raise ProblemError(
            f"problem {name!r}: the {what} function must return a 1-D array for one vector of "
            f"shape {x.shape}, got shape {shape}"
        )
    return int(shape[0])


def _validated(
    objective: Any, inequality: Any, equality: Any, lower: Any, upper: Any, name: Any,
    f_star: Any,
) -> dict[str, Any]:
    """The checked fields of a :class:`ConstrainedProblem` (one clear ProblemError if bad)."""
    if not callable(objective):
        raise ProblemError(f"problem {name!r}: objective must be a function of one vector")
    for what, fn in (("inequality", inequality), ("equality", equality)):
        if fn is not None and not callable(fn):
            raise ProblemError(f"problem {name!r}: {what} must be a function or None")
    dtype = jnp.zeros(()).dtype  # float32, or float64 inside float64()
    try:
        lo = np.asarray(lower, dtype=np.float64)
        hi = np.asarray(upper, dtype=np.float64)
    except (TypeError, ValueError):
        raise ProblemError(f"problem {name!r}: bounds must be numeric vectors") from None
    if lo.ndim == 0 and hi.ndim == 1:
        lo = np.full_like(hi, lo)
    if hi.ndim == 0 and lo.ndim == 1:
        hi = np.full_like(lo, hi)
    if lo.ndim != 1 or hi.ndim != 1 or lo.shape != hi.shape or lo.size == 0:
        raise ProblemError(
            f"problem {name!r}: lower and upper must be 1-D vectors of the same length, got "
            f"shapes {lo.shape} and {hi.shape}"
        )
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ProblemError(f"problem {name!r}: bounds must be finite (found NaN or inf)")
    bad = np.nonzero(lo > hi)[0]
    if bad.size:
        i = int(bad[0])
        raise ProblemError(
            f"problem {name!r}: bounds reversed at coordinate {i}: lower={lo[i]} > upper={hi[i]}"
        )
    if f_star is not None and not math.isfinite(float(f_star)):
        raise ProblemError(f"problem {name!r}: f_star must be a finite number or None")
    inequality = _no_constraints if inequality is None else inequality
    equality = _no_constraints if equality is None else equality
    probe = jax.ShapeDtypeStruct(lo.shape, dtype)
    _output_size(objective, probe, "objective", name)
    p = _output_size(inequality, probe, "inequality", name)
    q = _output_size(equality, probe, "equality", name)
    return dict(
        lower=jnp.asarray(lo, dtype),
        upper=jnp.asarray(hi, dtype),
        objective=objective,
        inequality=inequality,
        equality=equality,
        name=str(name),
        f_star=None if f_star is None else float(f_star),
        num_inequality=p,
        num_equality=q,
    )
