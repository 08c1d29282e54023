"""The gait search with two objectives: speed against endurance, or speed against electrical CoT.

``make_gait_mo_problem(second="endurance" | "cot", ...)`` returns a
:class:`MultiObjectiveGaitProblem`, a problem of kind ``"multiobjective"`` (for
``strategies.MOEACO`` through ``ea.minimize``, vmapped seeds included) whose batched
``evaluate(X, key)`` runs the same batched rollout over R randomised worlds of the
optimisation stream as the constrained gait problem
(:class:`~eaco_jax.problems.gait.ConstrainedGaitProblem`) and returns
``Evaluation(f, violation)`` with ``f`` of shape ``(ants, 2)``, both columns minimised:

* ``f[:, 0] = -speed``: the constrained problem's objective (fitness distance over the
  horizon per world, combined over the worlds by ``robust.aggregate``, CVaR by default);
* ``second="endurance"``: ``f[:, 1] = -min(endurance, ENDURANCE_CEILING_MIN)``, the minutes
  of continuous walking from ambient until the first winding reaches the firmware limit
  (:mod:`eaco_jax.gait.motors`), in the worst world. A gait whose windings never reach the
  limit has an infinite endurance; the ceiling (60 min) makes it finite, so every gait past an
  hour counts the same;
* ``second="cot"``: ``f[:, 1] = min(electrical CoT, COT_CEILING)``, the electrical cost of
  transport (I^2 R losses plus mechanical work, over m g d), the mean over the worlds as
  ``GaitProblem.metrics`` reports it; a gait that does not move (no CoT) gets the ceiling.

``violation`` is the sum of the normalised constraints of :mod:`eaco_jax.gait.constraints`
other than ``endurance`` (current, slip, drift, falls), since endurance is now an objective.

``ref_point`` (for the hypervolume every run reports): ``(0, 0)`` for endurance (0 m/s, 0 min:
the hypervolume is in m/s x min) and ``(0, COT_CEILING)`` for CoT. A point at or beyond the
reference in either objective (standing still, CoT at the ceiling) adds nothing.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.gait import constraints as gc
from eaco_jax.gait import quality as ql
from eaco_jax.gait.fitness import aggregate
from eaco_jax.gait.worlds import RobustConfig, Worlds
from eaco_jax.problems.base import Evaluation, ProblemError
from eaco_jax.problems.gait import ConstrainedGaitProblem, make_gait_problem

#: the second objectives
SECOND = ("endurance", "cot")
ENDURANCE_CEILING_MIN = 60.0
"""Endurance is capped at this many minutes (an endless one would be +inf)."""
COT_CEILING = 10.0
"""Electrical CoT is capped here; a gait with no CoT (it did not move) gets it."""


@struct.dataclass
class MultiObjectiveGaitProblem(ConstrainedGaitProblem):
    """Minimise ``(-speed, -endurance)`` or ``(-speed, electrical CoT)`` of a gait subject to
    the current, slip, drift and fall constraints (see the module docstring)."""

    second: str = struct.field(pytree_node=False, default="endurance")

    kind: ClassVar[str] = "multiobjective"
    num_objectives: ClassVar[int] = 2
    #: the driver's single-objective re-check does not apply (a front has no single best)
    host_check: ClassVar[None] = None

    @property
    def objective_names(self) -> tuple[str, str]:
        """``("-speed", "-endurance_min")`` or ``("-speed", "electrical_cot")``."""
        return ("-speed", "-endurance_min" if self.second == "endurance" else "electrical_cot")

    @property
    def ref_point(self) -> jax.Array:
        """The hypervolume's reference point ``(2,)``: no speed and no endurance, or no speed
        and the CoT ceiling."""
        second = 0.0 if self.second == "endurance" else COT_CEILING
        return jnp.asarray([0.0, second], self.dtype)

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return tuple(c for c in gc.names(self.turn) if c != "endurance")

    def objectives(self, solutions: jax.Array, worlds: Worlds | None = None
                   ) -> tuple[jax.Array, jax.Array, dict[str, jax.Array]]:
        """Objectives ``f`` ``(m, 2)``, normalised constraints ``g`` ``(m, p)`` and the raw
        values ``{"speed", "endurance_min", "electrical_cot", <constraint>: (m,)}`` of gaits
        ``(m, dim)`` in ``worlds`` (None: the nominal world), from one batched rollout."""
        res = self.rollout(solutions, worlds, quality=True)
        per_world = res["fitness"] / self.horizon
        if worlds is None:
            speed = per_world[:, 0]
        else:
            cfg = self.robust or RobustConfig()
            speed = aggregate(per_world, cfg.aggregate, cfg.alpha)
        speed = jnp.where(jnp.isfinite(speed), speed, 0.0)
        endurance = jnp.min(res["min_endurance_min"], axis=1)
        endurance = jnp.where(jnp.isnan(endurance), 0.0, endurance)
        cot = jnp.nanmean(res["electrical_cot"], axis=1)
        cot = jnp.where(jnp.isfinite(cot), cot, COT_CEILING)
        if self.second == "endurance":
            second = -jnp.minimum(endurance, ENDURANCE_CEILING_MIN)
        else:
            second = jnp.minimum(cot, COT_CEILING)
        vals = gc.values(res, self.turn)
        vals.pop("endurance")
        g = gc.normalised(vals, ql.mo.motor_model(self.spec), self.horizon,
                          1 if worlds is None else worlds.size)
        f = jnp.stack([-speed, second], axis=-1).astype(self.dtype)
        return f, g, {"speed": speed, "endurance_min": endurance, "electrical_cot": cot, **vals}

    def evaluate(self, solutions: jax.Array, key: jax.Array | None = None) -> Evaluation:
        """``Evaluation(f (m, 2), violation (m,))`` of a colony ``(m, dim)`` in the worlds
        ``key`` picks from the optimisation stream (key-less: its batch 0)."""
        x, worlds = self.colony_in_worlds(solutions, key)
        f, g, _ = self.objectives(x, worlds)
        return Evaluation(f=f, violation=gc.violation(g).astype(self.dtype))

    def evaluate_in(self, solutions: jax.Array, worlds: Worlds | None) -> Evaluation:
        """:meth:`evaluate` in given worlds (e.g. the selection stream's, to score fronts)."""
        x = jnp.clip(solutions.astype(self.dtype), self.lower, self.upper)
        f, g, _ = self.objectives(x, worlds)
        return Evaluation(f=f, violation=gc.violation(g).astype(self.dtype))

    def report(self, params: Any, worlds: Worlds | None = None) -> dict[str, Any]:
        """One gait's objectives, violation, feasibility and constraint table in ``worlds``."""
        x = self.gait_row(params)
        f, g, vals = jax.jit(self.objectives)(x, worlds)
        v = float(np.asarray(gc.violation(g))[0])
        n = 1 if worlds is None else worlds.size
        cons = {k: np.asarray(vals[k])[0] for k in self.constraint_names}
        return {"f": [float(a) for a in np.asarray(f)[0]], "violation": v, "feasible": v <= 0.0,
                "speed": float(np.asarray(vals["speed"])[0]),
                "endurance_min": float(np.asarray(vals["endurance_min"])[0]),
                "electrical_cot": float(np.asarray(vals["electrical_cot"])[0]),
                "worlds": n,
                "constraints": gc.table(cons, np.asarray(g)[0], ql.mo.motor_model(self.spec),
                                        self.horizon, n)}


def make_gait_mo_problem(robot: Any = "nao", second: str = "endurance",
                         **kwargs: Any) -> MultiObjectiveGaitProblem:
    """A :class:`MultiObjectiveGaitProblem`: ``second`` is ``"endurance"`` or ``"cot"``; the
    other arguments are :func:`~eaco_jax.problems.gait.make_gait_problem`'s (``constrained``
    and ``penalty`` excluded: the constraints are always on, and there is no penalty)."""
    if second not in SECOND:
        raise ProblemError(f"second must be 'endurance' or 'cot', got {second!r}")
    for bad in ("constrained", "penalty", "penalty_weight"):
        if bad in kwargs:
            raise ProblemError(f"a multi-objective gait problem takes no {bad!r}: drop it (the "
                               "constraints are always on)")
    base = make_gait_problem(robot, constrained=True, **kwargs)
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    fields["name"] = f"{base.name}-speed-{second}"
    return MultiObjectiveGaitProblem(**fields, second=second)


__all__ = ["COT_CEILING", "ENDURANCE_CEILING_MIN", "SECOND", "MultiObjectiveGaitProblem",
           "make_gait_mo_problem"]
