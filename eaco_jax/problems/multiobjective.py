"""Multi-objective continuous problems: several objectives, box bounds, optional constraints.

A :class:`MultiObjectiveProblem` is built from plain JAX functions of ONE vector, as a
:class:`~eaco_jax.problems.ConstrainedProblem` is: ``objectives(x) -> (k,)`` (every entry
minimised), ``inequality(x) -> (p,)`` (feasible when every entry is <= 0) and
``equality(x) -> (q,)`` (feasible when every |entry| <= 1e-4). Its ``kind`` is
``"multiobjective"`` and ``evaluate`` returns an :class:`~eaco_jax.problems.Evaluation` whose
``f`` has shape ``(m, k)`` (one row of objectives per solution) and ``violation`` ``(m,)``,
so only strategies made for several objectives (``strategies.MOEACO``) accept it.

``ref_point`` ``(k,)`` is the fixed reference point of the hypervolume every run reports; a
problem whose true front is known carries it as ``true_front(n) -> (n, k)`` (numpy) and, where
it has a closed form, its hypervolume ``hv_star``.

Test problems with analytic fronts: ZDT1-3 (Zitzler, Deb & Thiele 2000, Evol. Comput.
8(2):173-195) and DTLZ2 (Deb, Thiele, Laumanns & Zitzler 2002, CEC, "Scalable
multi-objective optimization test problems").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.problems.base import Box, Evaluation, ProblemError
from eaco_jax.problems.constrained import _output_size, violation_of

Array = jax.Array


def _none(x: Array) -> Array:
    return jnp.zeros((0,), x.dtype)


@jax.tree_util.register_pytree_node_class
class MultiObjectiveProblem(Box):
    """Minimise every entry of ``objectives(x)`` s.t. ``inequality(x) <= 0``,
    ``equality(x) == 0``, in the box ``[lower, upper]``.

    Construction checks bounds, the reference point and the functions' output shapes
    (abstractly) and raises one :class:`ProblemError` line. A pytree: ``lower``, ``upper`` and
    ``ref_point`` are leaves; functions, name, ``true_front`` and ``hv_star`` are static.
    """

    kind: ClassVar[str] = "multiobjective"
    _STATIC = ("objectives", "inequality", "equality", "name", "true_front", "hv_star",
               "num_objectives", "num_inequality", "num_equality")

    def __init__(
        self,
        objectives: Callable[[Array], Array],
        inequality: Callable[[Array], Array] | None = None,
        equality: Callable[[Array], Array] | None = None,
        *,
        lower: Any,
        upper: Any,
        ref_point: Any,
        name: str = "multiobjective",
        true_front: Callable[[int], np.ndarray] | None = None,
        hv_star: float | None = None,
    ) -> None:
        if not callable(objectives):
            raise ProblemError(f"problem {name!r}: objectives must be a function of one vector "
                               "returning a (k,) array")
        for what, fn in (("inequality", inequality), ("equality", equality)):
            if fn is not None and not callable(fn):
                raise ProblemError(f"problem {name!r}: {what} must be a function or None")
        dtype = jnp.zeros(()).dtype
        try:
            lo = np.asarray(lower, np.float64)
            hi = np.asarray(upper, np.float64)
            ref = np.asarray(ref_point, np.float64)
        except (TypeError, ValueError):
            raise ProblemError(f"problem {name!r}: bounds and ref_point must be numeric "
                               "vectors") from None
        if lo.ndim == 0 and hi.ndim == 1:
            lo = np.full_like(hi, lo)
        if hi.ndim == 0 and lo.ndim == 1:
            hi = np.full_like(lo, hi)
        if lo.ndim != 1 or lo.shape != hi.shape or lo.size == 0:
            raise ProblemError(f"problem {name!r}: lower and upper must be 1-D vectors of the "
                               f"same length, got shapes {lo.shape} and {hi.shape}")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(lo > hi):
            raise ProblemError(f"problem {name!r}: bounds must be finite with lower <= upper")
        probe = jax.ShapeDtypeStruct(lo.shape, dtype)
        try:
            out = jax.eval_shape(objectives, probe)
        except Exception as err:  # noqa: BLE001 - any failure in user code is a problem error
            raise ProblemError(f"problem {name!r}: the objectives function fails on a vector "
                               f"of shape {lo.shape}: {type(err).__name__}") from None
        shape = getattr(out, "shape", None)
        if shape is None or len(shape) != 1 or shape[0] < 2:
            raise ProblemError(f"problem {name!r}: objectives must return a (k,) array with "
                               f"k >= 2 for one vector, got shape {shape}")
        k = int(shape[0])
        if ref.shape != (k,) or not np.all(np.isfinite(ref)):
            raise ProblemError(f"problem {name!r}: ref_point must be {k} finite numbers (one "
                               f"per objective), got shape {ref.shape}")
        inequality = _none if inequality is None else inequality
        equality = _none if equality is None else equality
        fields = dict(
            objectives=objectives, inequality=inequality, equality=equality, name=str(name),
            true_front=true_front, hv_star=None if hv_star is None else float(hv_star),
            num_objectives=k,
            num_inequality=_output_size(inequality, probe, "inequality", name),
            num_equality=_output_size(equality, probe, "equality", name),
            lower=jnp.asarray(lo, dtype), upper=jnp.asarray(hi, dtype),
            ref_point=jnp.asarray(ref, dtype),
        )
        for key, value in fields.items():
            object.__setattr__(self, key, value)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("MultiObjectiveProblem is immutable")

    def tree_flatten(self) -> tuple[tuple[Array, Array, Array], tuple]:
        return (self.lower, self.upper, self.ref_point), tuple(
            getattr(self, s) for s in self._STATIC)

    @classmethod
    def tree_unflatten(cls, aux: tuple, leaves: tuple) -> MultiObjectiveProblem:
        obj = object.__new__(cls)
        for key, value in zip(cls._STATIC, aux, strict=True):
            object.__setattr__(obj, key, value)
        for key, value in zip(("lower", "upper", "ref_point"), leaves, strict=True):
            object.__setattr__(obj, key, value)
        return obj

    def __repr__(self) -> str:
        return (f"MultiObjectiveProblem(name={self.name!r}, dim={self.dim}, "
                f"objectives={self.num_objectives}, inequality={self.num_inequality}, "
                f"equality={self.num_equality})")

    def constraints(self, x: Array) -> tuple[Array, Array]:
        """``(g(x), h(x))`` for one vector."""
        return (jnp.asarray(self.inequality(x), x.dtype).reshape(self.num_inequality),
                jnp.asarray(self.equality(x), x.dtype).reshape(self.num_equality))

    def evaluate_one(self, x: Array) -> tuple[Array, Array]:
        """Objectives ``(k,)`` and total violation of one vector."""
        f = jnp.asarray(self.objectives(x), x.dtype).reshape(self.num_objectives)
        g, h = self.constraints(x)
        return f, violation_of(g, h)

    def evaluate(self, solutions: Array) -> Evaluation:
        """Objectives ``(m, k)`` and violations ``(m,)`` of a batch ``(m, n)`` of vectors."""
        if not isinstance(solutions, jax.core.Tracer):
            shape = np.shape(solutions)
            if len(shape) != 2 or shape[1] != self.dim:
                raise ProblemError(f"problem {self.name!r}: evaluate takes points of shape "
                                   f"(m, {self.dim}), got {shape}")
        f, v = jax.vmap(self.evaluate_one)(solutions)
        return Evaluation(f=f, violation=v)

    def shown_best(self, cost: float) -> float:
        """The hypervolume a multi-objective colony's ``best_cost`` (its negative) stands for."""
        return -cost


# --------------------------------------------------------------------------- ZDT
def _zdt_g(x: Array) -> Array:
    return 1.0 + 9.0 * jnp.sum(x[1:]) / (x.shape[0] - 1)


def _zdt1(x: Array) -> Array:
    g = _zdt_g(x)
    return jnp.stack([x[0], g * (1.0 - jnp.sqrt(x[0] / g))])


def _zdt2(x: Array) -> Array:
    g = _zdt_g(x)
    return jnp.stack([x[0], g * (1.0 - (x[0] / g) ** 2)])


def _zdt3(x: Array) -> Array:
    g = _zdt_g(x)
    r = x[0] / g
    return jnp.stack([x[0], g * (1.0 - jnp.sqrt(r) - r * jnp.sin(10.0 * jnp.pi * x[0]))])


def _nondominated(points: np.ndarray) -> np.ndarray:
    """The rows of ``points`` (2 objectives) no other row dominates, sorted by f1."""
    p = points[np.lexsort((points[:, 1], points[:, 0]))]
    keep = p[:, 1] < np.minimum.accumulate(np.concatenate([[np.inf], p[:-1, 1]]))
    return p[keep]


def zdt_front(which: int, n: int) -> np.ndarray:
    """``n`` points of ZDT``which``'s true Pareto front (g = 1), f1 evenly spaced (ZDT3: the
    non-dominated part of its curve, so fewer than ``n`` points)."""
    f1 = np.linspace(0.0, 1.0, n)
    if which == 1:
        return np.stack([f1, 1.0 - np.sqrt(f1)], axis=1)
    if which == 2:
        return np.stack([f1, 1.0 - f1**2], axis=1)
    return _nondominated(np.stack(
        [f1, 1.0 - np.sqrt(f1) - f1 * np.sin(10.0 * np.pi * f1)], axis=1))


#: ZDT's reference point for the hypervolume (each objective's range on the front, plus 0.1)
ZDT_REF = (1.1, 1.1)
#: exact hypervolume of the true front w.r.t. ZDT_REF: integral of (1.1 - f2(f1)) over [0, 1]
#: plus the strip f1 in [1, 1.1] at height 1.1
_ZDT_HV = {1: 0.1 + 2.0 / 3.0 + 0.11, 2: 0.1 + 1.0 / 3.0 + 0.11}


def zdt(which: int = 1, dim: int = 30) -> MultiObjectiveProblem:
    """ZDT1 (convex front f2 = 1 - sqrt f1), ZDT2 (concave, 1 - f1^2) or ZDT3 (disconnected),
    ``dim`` variables in [0, 1]; the front is at x_2 = ... = x_dim = 0."""
    fns = {1: _zdt1, 2: _zdt2, 3: _zdt3}
    if which not in fns:
        raise ProblemError(f"ZDT{which} is not provided; choose 1, 2 or 3")
    if int(dim) < 2:
        raise ProblemError(f"zdt{which} needs dim >= 2, got {dim}")
    return MultiObjectiveProblem(
        fns[which], lower=np.zeros(int(dim)), upper=np.ones(int(dim)), ref_point=ZDT_REF,
        name=f"zdt{which}", true_front=lambda n, w=which: zdt_front(w, n),
        hv_star=_ZDT_HV.get(which))


def zdt1(dim: int = 30) -> MultiObjectiveProblem:
    """ZDT1 with ``dim`` variables (30 in the original suite)."""
    return zdt(1, dim)


def zdt2(dim: int = 30) -> MultiObjectiveProblem:
    """ZDT2 with ``dim`` variables (30 in the original suite)."""
    return zdt(2, dim)


def zdt3(dim: int = 30) -> MultiObjectiveProblem:
    """ZDT3 with ``dim`` variables (30 in the original suite)."""
    return zdt(3, dim)


# --------------------------------------------------------------------------- DTLZ2
def _dtlz2(x: Array, k: int) -> Array:
    g = jnp.sum((x[k - 1:] - 0.5) ** 2)
    ang = x[: k - 1] * (jnp.pi / 2.0)
    # cos(pi/2) rounds to -4e-8 in float32: clamped at 0 (its true value), or a point at the
    # bound x_i = 1 with a larger g would get a smaller objective and never be dominated
    cos = jnp.maximum(jnp.cos(ang), 0.0)
    c = jnp.concatenate([jnp.ones((1,), x.dtype), jnp.cumprod(cos)])
    s = jnp.concatenate([jnp.ones((1,), x.dtype), jnp.sin(ang[::-1])])
    return (1.0 + g) * c[::-1] * s


def simplex_lattice(k: int, divisions: int) -> np.ndarray:
    """Das-Dennis points: every k-vector of multiples of 1/divisions summing to 1."""
    def rec(left: int, parts: int) -> list[list[int]]:
        if parts == 1:
            return [[left]]
        return [[i, *rest] for i in range(left + 1) for rest in rec(left - i, parts - 1)]

    return np.asarray(rec(divisions, k), np.float64) / divisions


def dtlz2_front(k: int, n: int) -> np.ndarray:
    """About ``n`` points of DTLZ2's front (the unit sphere's positive orthant): a simplex
    lattice projected radially onto the sphere."""
    d = 1
    while math.comb(d + 1 + k - 1, k - 1) <= n:
        d += 1
    w = simplex_lattice(k, d)
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def dtlz2(dim: int = 12, num_objectives: int = 3) -> MultiObjectiveProblem:
    """DTLZ2 with ``dim`` variables in [0, 1] and ``num_objectives`` objectives; the front is
    the unit sphere's positive orthant, reached at x_k = ... = x_dim = 0.5."""
    k = int(num_objectives)
    if k < 2 or int(dim) < k:
        raise ProblemError(f"dtlz2 needs num_objectives >= 2 and dim >= num_objectives, got "
                           f"dim={dim}, num_objectives={num_objectives}")
    # hypervolume of the front w.r.t. (1.1, ..., 1.1): the box minus the unit ball's orthant
    hv = 1.1**k - math.pi ** (k / 2) / math.gamma(k / 2 + 1) / 2**k
    return MultiObjectiveProblem(
        lambda x: _dtlz2(x, k), lower=np.zeros(int(dim)), upper=np.ones(int(dim)),
        ref_point=(1.1,) * k, name=f"dtlz2_{k}", true_front=lambda n: dtlz2_front(k, n),
        hv_star=hv)
