"""Quality-diversity problems: every solution has a fitness and a descriptor.

A QD problem (``kind = "qd"``) is a continuous problem (box ``lower``/``upper``, ``dim``,
``dtype``) whose batched ``evaluate(X)`` returns a :class:`QDEvaluation`: ``f`` ``(m,)`` the cost
(minimised, as everywhere in eaco_jax: ``-fitness``) and ``descriptors`` ``(m, d)``, the
measured behaviour that says which cell of an archive the solution belongs to. The problem
also carries its descriptor space, ``descriptor_lower``/``descriptor_upper`` ``(d,)``, and
``qd_offset``: the QD score of an archive is ``sum over filled cells (qd_offset - cost)``
(QDax's ``default_qd_metrics`` with fitness ``-cost``), so a problem picks the offset that
makes every filled cell count positively.

:class:`RastriginProj` is the analytic toy (Rastrigin with a folded 2-D descriptor: the means
of the two halves of ``x``, as QDax's ``rastrigin_proj`` benchmark): uniform samples' means
crowd the centre of the descriptor space, so filling the outer cells takes search.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ProblemError
from eaco_jax.problems.base import Box

Array = jax.Array

RASTRIGIN_BOX = 5.12
"""Rastrigin's usual box: every coordinate in [-5.12, 5.12]."""


@struct.dataclass
class QDEvaluation:
    """Batched result of a QD problem: cost ``f`` ``(m,)`` (minimised) and the behaviour
    ``descriptors`` ``(m, d)``."""

    f: Array
    descriptors: Array


@struct.dataclass
class RastriginProj(Box):
    """Minimise Rastrigin ``10 n + sum(x^2 - 10 cos(2 pi x))`` in ``[-5.12, 5.12]^n``; the
    descriptor is ``(mean(x[:n/2]), mean(x[n/2:]))`` in ``[-5.12, 5.12]^2``.

    ``qd_offset = 46.2144 n`` (``10 + 5.12^2 + 10`` per coordinate) bounds every cost from
    above, so each filled cell adds at least 0 to the QD score. Every cell's best cost is 0 only
    in the cell holding the descriptor (0, 0); elsewhere it is the Rastrigin of the closest
    point to the origin whose halves have those means.
    """

    lower: Array
    upper: Array
    descriptor_lower: Array
    descriptor_upper: Array
    name: str = struct.field(pytree_node=False, default="rastrigin-proj")

    kind: ClassVar[str] = "qd"
    differentiable = False

    @property
    def num_descriptors(self) -> int:
        return int(self.descriptor_lower.shape[-1])

    @property
    def qd_offset(self) -> float:
        return (20.0 + RASTRIGIN_BOX**2) * self.dim

    def shown_best(self, cost: float) -> float:
        """A QD strategy's ``best_cost`` is minus the QD score: show the score."""
        return -cost

    def evaluate(self, solutions: Array) -> QDEvaluation:
        """Cost and descriptor of a batch ``(m, dim)`` (clipped into the box)."""
        if solutions.ndim != 2 or solutions.shape[-1] != self.dim:
            raise ProblemError(f"{self.name}: solutions must be (m, {self.dim}), got "
                               f"{tuple(solutions.shape)}")
        x = jnp.clip(solutions.astype(self.dtype), self.lower, self.upper)
        n = self.dim
        cost = 10.0 * n + jnp.sum(x * x - 10.0 * jnp.cos(2.0 * jnp.pi * x), axis=-1)
        half = n // 2
        desc = jnp.stack([jnp.mean(x[:, :half], axis=-1), jnp.mean(x[:, half:], axis=-1)], -1)
        return QDEvaluation(f=cost.astype(self.dtype), descriptors=desc.astype(self.dtype))


def rastrigin_proj(dim: int = 8) -> RastriginProj:
    """The toy QD problem in ``dim`` (even, >= 2) dimensions."""
    if not isinstance(dim, int) or dim < 2 or dim % 2:
        raise ProblemError(f"rastrigin_proj needs an even dim >= 2, got {dim!r}")
    box = jnp.full((dim,), RASTRIGIN_BOX, jnp.float32)
    dbox = jnp.full((2,), RASTRIGIN_BOX, jnp.float32)
    return RastriginProj(lower=-box, upper=box, descriptor_lower=-dbox, descriptor_upper=dbox)


def check_qd_problem(problem: Any, who: str) -> None:
    """One :class:`ProblemError` line unless ``problem`` is a QD problem (kind ``"qd"``, box
    bounds, finite descriptor bounds with lower < upper, a finite ``qd_offset``)."""
    needed = ("lower", "upper", "descriptor_lower", "descriptor_upper", "qd_offset")
    if getattr(problem, "kind", None) != "qd" or not all(hasattr(problem, a) for a in needed):
        raise ProblemError(
            f"{who} needs a quality-diversity problem (kind 'qd': box bounds, descriptor_lower/"
            f"upper, qd_offset; e.g. eaco_jax.problems.qd.rastrigin_proj()), got "
            f"{type(problem).__name__}")
    lo, hi = problem.descriptor_lower, problem.descriptor_upper
    if not isinstance(lo, jax.core.Tracer):
        import numpy as np

        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        if lo.ndim != 1 or lo.shape != hi.shape or not (
                np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
            raise ProblemError(f"{getattr(problem, 'name', '')}: descriptor bounds must be "
                               "finite 1-D vectors of one length with lower < upper")
    if not math.isfinite(float(problem.qd_offset)):
        raise ProblemError(f"{getattr(problem, 'name', '')}: qd_offset must be finite")


__all__ = ["QDEvaluation", "RastriginProj", "check_qd_problem", "rastrigin_proj"]
