"""A gait library as a quality-diversity problem: walk-engine parameters -> how robustly the gait
walks, and what it does (forward speed, yaw rate[, lateral speed]).

Each evaluation rolls every gait out in the same ``R`` randomised worlds of the optimisation
stream (:mod:`eaco_jax.gait.worlds`; fresh worlds per evaluation when ``robust.resample``), one
batched rollout (:meth:`~eaco_jax.problems.gait.GaitProblem.walk_descriptors`), and returns a
:class:`~eaco_jax.problems.qd.QDEvaluation`:

* ``descriptors``: the world means of the measured forward speed (m/s, torso frame), yaw rate
  (deg/s, + = left) and, with ``lateral=True``, lateral speed (m/s, + = left): what a
  controller asks the library for (a unicycle's ``v`` and ``omega``).
* fitness (``f = -fitness``): robustness first, speed second: the fraction of the ``R`` worlds
  without a fall, plus the mean forward speed (m/s, at least 0) only when no world fell. A gait
  that falls in any world thus scores below 1 and one that never falls scores 1 + its speed.
  ``qd_offset = 0``: the QD score is the sum of the filled cells' fitness.

With ``constrained=True`` the library is filled under the motor constraints of
:mod:`eaco_jax.gait.constraints` (endurance, current, slip, falls; no drift: the yaw rate is
what a cell asks for), from the same batched rollout with the motor model: fitness ``1 +``
the forward speed (at least 0) where every constraint holds in every world, else
``1 / (1 + violation)``, so a feasible gait beats every infeasible one and among those the
smaller violation wins.

Cells' gaits are validated on the ``test`` stream (:func:`validate`), whose worlds no step of
the search saw.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.gait import constraints as gc
from eaco_jax.gait import quality as ql
from eaco_jax.gait.steer import Steering
from eaco_jax.gait.worlds import RobustConfig, optimisation_key, stream_key
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.gait import GaitProblem, make_gait_problem
from eaco_jax.problems.qd import QDEvaluation

Array = jax.Array

#: default descriptor box: forward speed (m/s), yaw rate (deg/s), lateral speed (m/s)
SPEED_RANGE = (-0.05, 0.35)
YAW_RANGE = (-40.0, 40.0)
LATERAL_RANGE = (-0.1, 0.1)


@struct.dataclass
class GaitLibraryProblem:
    """Gait parameters -> (robust speed fitness, measured forward speed and yaw rate
    [, lateral speed]); see the module docstring."""

    gait: GaitProblem
    descriptor_lower: Array
    descriptor_upper: Array
    lateral: bool = struct.field(pytree_node=False, default=False)
    constrained: bool = struct.field(pytree_node=False, default=False)
    name: str = struct.field(pytree_node=False, default="gait-library")

    #: the constraints of a constrained library: a turning gait's (no drift)
    constraint_names: ClassVar[tuple[str, ...]] = gc.names("library")

    kind: ClassVar[str] = "qd"
    differentiable = False
    qd_offset = 0.0

    @property
    def lower(self) -> Array:
        return self.gait.lower

    @property
    def upper(self) -> Array:
        return self.gait.upper

    @property
    def dim(self) -> int:
        return self.gait.dim

    @property
    def dtype(self) -> Any:
        return self.gait.dtype

    @property
    def num_descriptors(self) -> int:
        return 3 if self.lateral else 2

    @property
    def descriptor_names(self) -> tuple[str, ...]:
        names = ("forward_mps", "turn_deg_s")
        return names + ("lateral_mps",) if self.lateral else names

    @property
    def stochastic(self) -> bool:
        """Fresh optimisation-stream worlds each evaluation (the driver passes a key)."""
        return self.gait.stochastic

    @property
    def param_names(self) -> tuple[str, ...]:
        return self.gait.param_names

    def for_rows(self, rows: int) -> GaitLibraryProblem:
        """This problem for ``rows`` vmapped copies of its evaluation: the gait problem's
        (:meth:`~eaco_jax.problems.gait.GaitProblem.for_rows`: MuJoCo Warp's contact buffer)."""
        gait = self.gait.for_rows(rows)
        return self if gait is self.gait else self.replace(gait=gait)

    def shown_best(self, cost: float) -> float:
        """A QD strategy's ``best_cost`` is minus the QD score: show the score."""
        return -cost

    def measure(self, solutions: Array, worlds: Any = None) -> dict[str, Array]:
        """Per-world measurements ``(m, R)`` of gaits ``(m, dim)`` (clipped into the box)."""
        x = jnp.clip(solutions.astype(self.dtype), self.lower, self.upper)
        return self.gait.walk_descriptors(x, worlds, quality=self.constrained)

    def constraint_values(self, res: dict[str, Array]) -> tuple[dict[str, Array], Array]:
        """Each constraint's value ``{name: (m,)}`` (worst world) and the total normalised
        violation ``(m,)`` of per-world measurements of a constrained library."""
        vals = gc.values(res, "library")
        g = gc.normalised(vals, ql.mo.motor_model(self.gait.spec), self.gait.horizon,
                          res["fell"].shape[1])
        return vals, gc.violation(g)

    def score(self, res: dict[str, Array]) -> QDEvaluation:
        """Fitness and descriptors from per-world measurements ``(m, R)``."""
        fell = res["fell"].astype(jnp.float32)
        fwd = jnp.mean(res["forward_mps"], axis=1)
        if self.constrained:
            _, viol = self.constraint_values(res)
            fitness = jnp.where(viol <= 0, 1.0 + jnp.maximum(fwd, 0.0), 1.0 / (1.0 + viol))
        else:
            survived = 1.0 - jnp.mean(fell, axis=1)
            never = jnp.all(fell == 0, axis=1)
            fitness = survived + jnp.where(never, jnp.maximum(fwd, 0.0), 0.0)
        cols = [fwd, jnp.mean(res["turn_deg_s"], axis=1)]
        if self.lateral:
            cols.append(jnp.mean(res["lateral_mps"], axis=1))
        desc = jnp.stack(cols, -1)
        ok = jnp.all(jnp.isfinite(desc), axis=-1) & jnp.isfinite(fitness)
        return QDEvaluation(f=jnp.where(ok, -fitness, jnp.inf).astype(self.dtype),
                            descriptors=desc.astype(self.dtype))

    def evaluate(self, solutions: Array, key: Array | None = None) -> QDEvaluation:
        """Cost (``-fitness``) and descriptors of a colony ``(m, dim)`` in the worlds ``key``
        picks from the optimisation stream (no key: the stream's batch 0)."""
        if solutions.ndim != 2 or solutions.shape[-1] != self.dim:
            raise ProblemError(f"{self.name}: solutions must be (ants, {self.dim}), got "
                               f"{tuple(solutions.shape)}")
        worlds = None
        if self.gait.robust is not None:
            k = None if key is None else optimisation_key(self.gait.robust.seed, key)
            worlds = self.gait.worlds(k)
        return self.score(self.measure(solutions, worlds))


def make_gait_library_problem(
    robot: str = "nao",
    backend: str = "auto",
    horizon: float = 3.0,
    worlds: int = 2,
    seed: int = 0,
    speed_range: tuple[float, float] = SPEED_RANGE,
    yaw_range: tuple[float, float] = YAW_RANGE,
    lateral_range: tuple[float, float] | None = None,
    impl: str = "auto",
    robust: RobustConfig | None = None,
    constrained: bool = False,
    steering: Steering | None = None,
) -> GaitLibraryProblem:
    """The gait-library problem of ``robot`` (a biped: the walk engine's direction and turn
    rate give the descriptors' range): ``horizon`` seconds per rollout, ``worlds`` randomised
    worlds per evaluation from the optimisation stream of ``seed`` (0: the nominal world only;
    ``robust`` overrides both with a full :class:`RobustConfig`); descriptor ranges for the
    grid (``lateral_range`` adds the lateral speed as a third descriptor); ``constrained``
    fills it under the motor constraints (see the module docstring); ``steering`` closes each
    cell's heading loop (it must track the cell's turn: ``Steering(track_turn=True)``)."""
    if not isinstance(worlds, int) or worlds < 0:
        raise ProblemError(f"worlds must be an int >= 0, got {worlds!r}")
    if robust is None and worlds > 0:
        robust = RobustConfig(R=worlds, aggregate="mean", seed=int(seed))
    if steering is not None and not (isinstance(steering, Steering) and steering.track_turn):
        raise ProblemError("a library cell asks for its turn rate: steer it with "
                           "Steering(track_turn=True), or drop steering")
    gait = make_gait_problem(robot, backend=backend, horizon=horizon, robust=robust, impl=impl,
                             constrained=constrained, steering=steering)
    if gait.spec.gait != "biped":
        raise ProblemError(f"the gait library needs a biped's walk engine (direction and turn "
                           f"rate); robot {gait.spec.name!r} is a {gait.spec.gait}: use a "
                           "biped such as nao or op3")
    ranges = [speed_range, yaw_range] + ([lateral_range] if lateral_range is not None else [])
    for label, r in zip(("speed_range", "yaw_range", "lateral_range"), ranges, strict=False):
        if (len(r) != 2 or not all(isinstance(v, int | float) and math.isfinite(v) for v in r)
                or not r[0] < r[1]):
            raise ProblemError(f"{label} must be two finite numbers (low, high) with low < "
                               f"high, got {r!r}")
    lo = jnp.asarray([r[0] for r in ranges], jnp.float32)
    hi = jnp.asarray([r[1] for r in ranges], jnp.float32)
    return GaitLibraryProblem(gait=gait, descriptor_lower=lo, descriptor_upper=hi,
                              lateral=lateral_range is not None, constrained=constrained,
                              name=f"gait-library-{gait.spec.name}"
                              + ("-constrained" if constrained else ""))


def validate(problem: GaitLibraryProblem, x: Any, trials: int, seed: int = 0,
             batch: int = 0, chunk: int = 64) -> dict[str, np.ndarray]:
    """Each gait ``(k, dim)`` in ``trials`` randomised worlds of the TEST stream of ``seed``
    (``stream_key(seed, "test", batch)``; worlds nothing in a search chose on), as host arrays
    ``(k,)``: ``fall_rate`` and the world means of ``forward_mps``, ``turn_deg_s``,
    ``lateral_mps``; a constrained library's also ``violation`` (over the test worlds, 0:
    every constraint holds in each) and each constraint's worst-world value; gaits go
    ``chunk`` at a time (one batched rollout each)."""
    cfg = problem.gait.robust or RobustConfig(aggregate="mean", seed=int(seed))
    gait = problem.gait.replace(robust=dataclasses.replace(cfg, seed=int(seed)))
    worlds = gait.worlds(stream_key(int(seed), "test", int(batch)), n=int(trials))
    x = np.asarray(x, np.float32).reshape(-1, problem.dim)

    def run_one(xs):
        res = problem.measure(xs, worlds)
        out = {"fall_rate": jnp.mean(res["fell"].astype(jnp.float32), axis=1),
               **{k: jnp.mean(res[k], axis=1)
                  for k in ("forward_mps", "turn_deg_s", "lateral_mps")}}
        if problem.constrained:
            vals, out["violation"] = problem.constraint_values(res)
            out.update({f"{k}_worst": v for k, v in vals.items()})
        return out

    run = jax.jit(run_one)
    out: dict[str, list] = {}
    for i in range(0, len(x), chunk):
        part = x[i:i + chunk]
        pad = np.concatenate([part, np.repeat(part[-1:], chunk - len(part), 0)])
        for k, v in run(jnp.asarray(pad)).items():
            out.setdefault(k, []).append(np.asarray(v)[:len(part)])
    if not out:
        out = {k: [] for k in ("fall_rate", "forward_mps", "turn_deg_s", "lateral_mps")}
    return {k: np.concatenate(v) if v else np.zeros((0,), np.float32) for k, v in out.items()}


__all__ = ["GaitLibraryProblem", "make_gait_library_problem", "validate"]
