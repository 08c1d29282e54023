"""What a problem is to the colony.

A problem is a pytree (a ``flax.struct`` dataclass: arrays are leaves, configuration is
static) with

* ``kind``: ``"graph"`` (solutions are permutations / node sequences, e.g. TSP tours),
  ``"path"`` (node sequences from a start to a goal), ``"continuous"`` (real vectors inside box
  bounds) or ``"multiobjective"``; declared as a class constant, ``kind: ClassVar[str] =
  "graph"`` (not a field: it is no setting); a wrapper whose kind is its inner problem's
  (:class:`~eaco_jax.problems.sharding.Sharded`) returns it from a read-only property, the
  form :class:`Problem` declares;
* ``name``: a short identifier used in results and checkpoints;
* ``evaluate(solutions) -> fitness``: pure and batched over the leading (ant) axis, so the
  whole colony is evaluated in one traced call. Graph problems return ``(m,)`` costs; continuous
  problems return an :class:`Evaluation` (objective and total constraint violation).

Problems know nothing about strategies. Everything is minimised.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import jax
from flax import struct

from eaco_jax.errors import ProblemError  # noqa: F401  (re-exported)


@struct.dataclass
class Evaluation:
    """Batched result of a continuous problem: objective ``f`` and violation (0 = feasible).

    ``f`` is ``(m,)``, or ``(m, k)`` for a multi-objective problem (one row per solution)."""

    f: jax.Array
    violation: jax.Array


@runtime_checkable
class Problem(Protocol):
    @property
    def kind(self) -> str: ...

    name: str

    def evaluate(self, solutions: jax.Array) -> Any: ...


class Box:
    """``dim`` and ``dtype`` of a problem searched inside its box ``lower`` .. ``upper`` (a
    mixin for the ``flax.struct`` problem classes that hold those arrays)."""

    @property
    def dim(self) -> int:
        return int(self.lower.shape[-1])

    @property
    def dtype(self) -> Any:
        return self.lower.dtype
