"""Gait optimisation as a continuous problem: each ant is a walk-engine parameter vector.

``GaitProblem.evaluate(X)`` rolls the whole colony out as one batched simulation (MJX, or
MuJoCo's C engine through a ``jax.pure_callback``) and returns ``f = -fitness`` (the paper's
distance-based gait fitness, :mod:`eaco_jax.gait.fitness`; minimised, so lower is better) with
zero violation. ``backend="auto"`` picks ``"mjx"`` on GPU/TPU and ``"native"`` on CPU, where the
C engine is an order of magnitude faster. ``simulate(params)`` re-runs one gait and returns what
plots and reports need (time, joint angles, torso trajectory, speed, distance, fall, drift, and
the energy / gait-quality metrics of :mod:`eaco_jax.gait.quality`).

``robust=RobustConfig(R=8, aggregate="cvar", ...)`` evaluates every ant in R randomised worlds
(:mod:`eaco_jax.gait.worlds`), ants x R in one batched rollout, and aggregates the per-world
fitness. ``evaluate(X, key)`` draws the worlds from the optimisation stream of ``robust.seed``
(the run's seed), the batch picked by ``key`` (the driver's per-iteration key,
:func:`~eaco_jax.gait.worlds.optimisation_key`); without a key the worlds are that stream's
batch 0. Selection and test worlds come from the other two streams
(:data:`~eaco_jax.gait.worlds.STREAMS`), never seen by the search.
``penalty="power"`` or ``"cot"`` (weight ``penalty_weight``, off by default) subtracts the energy
cost from each world's fitness: ``"cot"``: ``d - w E / (m g)`` (= ``d (1 - w CoT)``),
``"power"``: ``d - w P_mean`` (metres per watt).

``constrained=True`` (a :class:`ConstrainedGaitProblem`) makes the search a constrained
problem with the colony's own constraint handling (epsilon-constrained, Deb, penalty): the
objective is speed (``f = -speed``, the fitness distance over the horizon, aggregated over the
worlds as the fitness is) and the violation the sum of the normalised constraints of
:mod:`eaco_jax.gait.constraints` (endurance, current, slip, drift, falls), all from the same
batched rollout; ``host_check`` re-checks the best and reports each constraint.

``steering=Steering(...)`` (:mod:`eaco_jax.gait.steer`, off by default) closes the heading loop
in every rollout: the walk engine's turn rate is corrected at each control step from the
torso's pose, so the gait is searched, selected and tested as the controller walks it.
"""

from __future__ import annotations

import math
import os
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.gait import constraints as gc
from eaco_jax.gait import quality as ql
from eaco_jax.gait.fitness import TURNS, GaitSummary, aggregate, gait_fitness, summarize
from eaco_jax.gait.robot import RobotSpec, known_robots, load_robot
from eaco_jax.gait.rollout_mjx import mjx_rollout
from eaco_jax.gait.rollout_native import (
    native_model,
    native_rollout,
    native_rollout_callback,
)
from eaco_jax.gait.steer import Steering, SteerInputs, turn_sensitivity
from eaco_jax.gait.walk_engine import (
    IK_CHOICES,
    PARAM_NAMES,
    bounds,
    control_sequence,
    gait_vector,
    param_names,
    uses_analytic_ik,
)
from eaco_jax.gait.worlds import (
    RobustConfig,
    Worlds,
    couple_controls,
    optimisation_key,
    sample_worlds,
    stream_key,
)
from eaco_jax.problems.base import Box, Evaluation, ProblemError

BACKENDS = ("auto", "mjx", "native")
PENALTIES = (None, "power", "cot")
QUALITY_SCALARS = ("energy_j", "mean_power_w", "peak_power_w", "cost_of_transport",
                   "peak_speed_frac", "peak_torque_frac", "foot_slip_m", "airborne_fraction",
                   "min_foot_gap_m")


@struct.dataclass
class GaitProblem(Box):
    """Maximise the walked distance (minimise ``-fitness``) over gait parameters in bounds."""

    lower: jax.Array
    upper: jax.Array
    spec: RobotSpec = struct.field(pytree_node=False)
    backend: str = struct.field(pytree_node=False, default="native")
    horizon: float = struct.field(pytree_node=False, default=20.0)
    direction_deg: float = struct.field(pytree_node=False, default=0.0)
    slope_deg: float = struct.field(pytree_node=False, default=0.0)
    accuracy: str = struct.field(pytree_node=False, default="fast")
    name: str = struct.field(pytree_node=False, default="gait")
    robust: RobustConfig | None = struct.field(pytree_node=False, default=None)
    penalty: str | None = struct.field(pytree_node=False, default=None)
    penalty_weight: float = struct.field(pytree_node=False, default=0.0)
    #: "left" / "right": score the heading turned (degrees) instead of the distance walked
    turn: str | None = struct.field(pytree_node=False, default=None)
    impl: str = struct.field(pytree_node=False, default="jax")  # MJX implementation: jax|warp
    #: the biped's leg IK: "auto", "analytic" (the NAO's) or "generic" (any leg chain)
    ik: str = struct.field(pytree_node=False, default="auto")
    #: the heading controller of :mod:`eaco_jax.gait.steer` (None: open loop)
    steering: Steering | None = struct.field(pytree_node=False, default=None)
    #: vmapped copies of each evaluation run as one MuJoCo Warp batch (seeds x settings of
    #: one ``minimize`` call): its contact buffer is shared by them all (:meth:`for_rows`)
    copies: int = struct.field(pytree_node=False, default=1)

    kind: ClassVar[str] = "continuous"
    differentiable = False  # a simulation: no gradient repair / refinement steps

    def for_rows(self, rows: int) -> GaitProblem:
        """This problem for ``rows`` vmapped copies of its evaluation (the driver's seeds x
        settings). MuJoCo Warp flattens an outer vmap into its one batch of worlds, whose
        contact buffer is sized per call; a buffer sized for one copy would drop the others'
        contacts. The JAX and native backends hold no such buffer: unchanged."""
        if self.backend != "mjx" or self.impl != "warp" or rows == self.copies:
            return self
        return self.replace(copies=int(rows))

    def shown_best(self, cost: float) -> float:
        """The best cost as the user reads it (the progress bar): the fitness, ``-cost``
        (the colony minimises ``-fitness``; a gait's fitness is maximised)."""
        return -cost

    @property
    def stochastic(self) -> bool:
        """Whether ``evaluate`` takes a ``key`` (fresh randomised worlds each evaluation)."""
        return self.robust is not None and self.robust.resample

    @property
    def param_names(self) -> tuple[str, ...]:
        return param_names(self.spec)

    @property
    def n_steps(self) -> int:
        """Control steps in the horizon."""
        return int(round(self.horizon / self.spec.control_dt))

    def controls(self, solutions: jax.Array) -> jax.Array:
        """The walk engine's joint targets ``(m, n_steps, nu)`` for gaits ``(m, dim)``."""
        heading = math.radians(self.direction_deg)
        return jax.vmap(lambda p: control_sequence(
            p, self.n_steps, self.spec, heading, self.slope_deg, self.ik))(solutions)

    def controls_and_steer(self, solutions: jax.Array) -> tuple[jax.Array, SteerInputs | None]:
        """:meth:`controls` of gaits ``(m, dim)`` and what the rollouts need to steer them (None
        without ``steering``): the targets' sensitivity to the turn rate, from the same
        forward pass, with the robot's joint coupling applied as the rollouts apply it to the
        targets."""
        if self.steering is None:
            return self.controls(solutions), None
        turn = PARAM_NAMES.index("turn_rate")
        u, d = turn_sensitivity(self.controls, solutions, turn)
        rates = solutions[:, turn] if self.steering.track_turn else None
        return u, SteerInputs(couple_controls(d, self.spec), self.steering,
                              math.radians(self.direction_deg), rates)

    def trace(self, solutions: jax.Array) -> jax.Array:
        """Torso traces ``(m, n_steps + 1, 6)`` of gaits ``(m, dim)`` in the nominal world."""
        return self._rollout(solutions, None, False)["trace"]

    def summarize(self, trace: jax.Array) -> GaitSummary:
        return summarize(trace[..., :3], trace[..., 3:6], self.spec.control_dt,
                         self.spec.fall_height, self.spec.fall_tilt_deg, self.slope_deg,
                         yaw=trace[..., 6])

    def worlds(self, key: jax.Array | None = None, n: int | None = None) -> Worlds:
        """The randomised worlds of one evaluation: ``n`` (default ``robust.R``) worlds drawn
        from ``key`` (default: fixed by ``robust.seed``)."""
        cfg = self.robust or RobustConfig()
        key = stream_key(cfg.seed, "optimisation", 0) if key is None else key
        nbody = native_model(self.spec, float(self.slope_deg), self.accuracy).nbody
        return sample_worlds(key, cfg, self.spec, nbody, self.n_steps, n)

    def _rollout(self, solutions, worlds: Worlds | None, quality: bool) -> dict:
        controls, steer = self.controls_and_steer(solutions)
        if self.backend == "mjx":
            return mjx_rollout(controls, self.spec, self.slope_deg, self.accuracy, worlds,
                               quality, impl=self.impl, steer=steer, copies=self.copies)
        return native_rollout_callback(controls, self.spec, self.slope_deg, self.accuracy,
                                       worlds, quality, steer=steer)

    def _measured(self, solutions: jax.Array, worlds: Worlds | None, quality: bool
                  ) -> tuple[jax.Array, GaitSummary, dict[str, jax.Array]]:
        """One batched rollout's trace, its summary and the flat ``(m * R, ...)`` results
        :meth:`rollout` and :meth:`walk_descriptors` both start from: the fitness of
        :func:`~eaco_jax.gait.fitness.gait_fitness` (no energy penalty), ``fall_time``, and
        with ``quality`` the metrics of :mod:`eaco_jax.gait.quality`."""
        if quality and not self.spec.has_motors:
            raise ProblemError(f"robot {self.spec.name!r} has no motor datasheet: no energy or "
                               "gait-quality metrics")
        nb = solutions.shape[0] * (1 if worlds is None else worlds.size)
        out = self._rollout(solutions, worlds, quality)
        summary = self.summarize(out["trace"])
        res = gait_fitness(summary, self.direction_deg, self.turn)
        res["fall_time"] = summary.fall_time
        if quality:
            res.update(self._quality(out["acc"], res["distance_m"], worlds, nb))
        return out["trace"], summary, res

    def rollout(self, solutions: jax.Array, worlds: Worlds | None = None,
                quality: bool = False) -> dict[str, jax.Array]:
        """Per-world results ``(m, R)`` of gaits ``(m, dim)`` (R = 1 without ``worlds``):
        ``fitness``, ``distance_m``, ``speed_mps``, ``fell``, ``drift_deg``, ``fall_time``, and
        with ``quality`` the metrics of :mod:`eaco_jax.gait.quality` (per-joint ones
        ``(m, R, nu)``). The fitness includes the problem's energy penalty, if any."""
        m, r = solutions.shape[0], 1 if worlds is None else worlds.size
        _, _, res = self._measured(solutions, worlds, quality)
        if quality:
            res["fitness"] = self._penalised(res)
        return {k: v.reshape((m, r) + v.shape[1:]) for k, v in res.items()}

    def walk_descriptors(self, solutions: jax.Array, worlds: Worlds | None = None,
                         quality: bool = False) -> dict[str, jax.Array]:
        """What each gait ``(m, dim)`` does in each world, ``(m, R)`` (R = 1 without
        ``worlds``), from one batched rollout: ``forward_mps`` and ``lateral_mps`` (the torso's
        displacement in its own heading frame, + = forward / left, per second walked, until
        the fall or the horizon; :func:`body_frame_speeds`), ``turn_deg_s`` (+ = left),
        ``fell`` and ``fitness`` (this problem's, without the energy penalty); with
        ``quality`` also everything :meth:`rollout` returns with it (what the constraints of
        :mod:`eaco_jax.gait.constraints` are computed from)."""
        m, r = solutions.shape[0], 1 if worlds is None else worlds.size
        trace, summary, res = self._measured(solutions, worlds, quality)
        if not quality:
            res = {k: res[k] for k in ("turn_deg_s", "fell", "fitness")}
        res["forward_mps"], res["lateral_mps"] = body_frame_speeds(
            trace, self.spec.control_dt, summary.fall_time)
        return {k: v.reshape((m, r) + v.shape[1:]) for k, v in res.items()}

    def _quality(self, acc, distance, worlds: Worlds | None, nb: int) -> dict:
        model = native_model(self.spec, float(self.slope_deg), self.accuracy)
        mass = float(np.sum(model.body_mass))
        nominal = jnp.asarray(self.spec.nominal_torque if self.spec.has_motors else
                              self.spec.force_limit, jnp.float32)
        if worlds is not None:
            r = worlds.size
            per_world = jnp.sum(jnp.asarray(model.body_mass) * worlds.mass_scale, -1)
            mass = jnp.take(per_world, jnp.arange(nb) % r)
            nominal = jnp.take(nominal * worlds.stall_scale, jnp.arange(nb) % r, axis=0)
        dt = float(model.opt.timestep)
        return ql.finalize(acc, distance, mass, dt, nominal, ql.mo.motor_model(self.spec))

    def _penalised(self, res: dict) -> jax.Array:
        fit = res["fitness"]
        if self.penalty is None or self.penalty_weight == 0.0:
            return fit
        model = native_model(self.spec, float(self.slope_deg), self.accuracy)
        if self.penalty == "cot":
            cost = res["energy_j"] / (float(np.sum(model.body_mass)) * ql.G)
        else:
            cost = res["mean_power_w"]
        return jnp.where(fit > 0, jnp.maximum(fit - self.penalty_weight * cost, 0.0), fit)

    def metrics(self, solutions: jax.Array, key: jax.Array | None = None,
                quality: bool = False) -> dict[str, jax.Array]:
        """Fitness, distance_m, speed_mps, fell, drift_deg, fall_time of each gait ``(m, dim)``.

        Nominal world without ``robust``; with it, ``fitness`` is the configured aggregate over
        the R worlds drawn from ``key``, ``fell`` the fraction of worlds with a fall and the rest
        means over worlds. ``quality`` adds the energy and gait-quality metrics (world means;
        peaks: world maxima)."""
        need_quality = quality or (self.penalty is not None and self.penalty_weight != 0.0)
        worlds = self.worlds(key) if self.robust is not None else None
        res = self.rollout(solutions, worlds, need_quality)
        if worlds is None:
            out = {k: v[:, 0] for k, v in res.items()}
        else:
            cfg = self.robust
            out = {k: jnp.mean(v.astype(jnp.float32), axis=1) for k, v in res.items()}
            out["fitness"] = aggregate(res["fitness"], cfg.aggregate, cfg.alpha)
            for k in ("peak_power_w", "peak_speed_frac", "peak_torque_frac",
                      "joint_peak_speed_frac", "joint_peak_torque_frac", "joint_peak_torque_nm",
                      "joint_peak_speed_rad_s", "peak_current_frac",
                      "peak_current_max_frac", "winding_10min_c", "winding_steady_c",
                      "winding_end_c"):
                if k in res:
                    out[k] = jnp.max(res[k], axis=1)
            for k in ("min_foot_gap_m", "endurance_min", "min_endurance_min"):
                if k in res:
                    out[k] = jnp.min(res[k], axis=1)
            if "electrical_cot" in res:
                out["electrical_cot"] = jnp.nanmean(res["electrical_cot"], axis=1)
            if "cost_of_transport" in res:
                out["cost_of_transport"] = jnp.nanmean(res["cost_of_transport"], axis=1)
        if not quality:
            out = {k: v for k, v in out.items() if k in _FITNESS_KEYS}
        return out

    def evaluate(self, solutions: jax.Array, key: jax.Array | None = None) -> Evaluation:
        """``Evaluation(f=-fitness, violation=0)`` for a colony ``(m, dim)``; ``key`` (the
        driver's) picks the batch of optimisation-stream worlds of a robust problem."""
        if solutions.ndim != 2 or solutions.shape[-1] != self.dim:
            raise ProblemError(
                f"gait problem {self.name!r}: solutions must be (ants, {self.dim}), "
                f"got {tuple(solutions.shape)}")
        x = jnp.clip(solutions.astype(self.dtype), self.lower, self.upper)
        if key is not None and self.robust is not None:
            key = optimisation_key(self.robust.seed, key)
        fit = self.metrics(x, key)["fitness"]
        fit = jnp.where(jnp.isfinite(fit), fit, 0.0).astype(self.dtype)
        return Evaluation(f=-fit, violation=jnp.zeros_like(fit))

    @property
    def constrained(self) -> bool:
        """Whether the search is constrained (a :class:`ConstrainedGaitProblem`)."""
        return False

    def gait_row(self, params: Any, what: str = "a gait") -> jax.Array:
        """One gait's parameters as a ``(1, dim)`` batch clipped to the search bounds, checked
        first (:func:`~eaco_jax.gait.walk_engine.gait_vector`: shape and finite values;
        ``what`` leads its error line)."""
        return jnp.clip(jnp.asarray(gait_vector(params, self.dim, what))[None], self.lower,
                        self.upper)

    @property
    def num_inequality(self) -> int:
        return 0

    def simulate(
        self, params: Any, record: bool = True, backend: str | None = None,
        horizon: float | None = None,
    ) -> dict[str, Any]:
        """Re-simulate one gait in the nominal world; metrics plus (if ``record``) time, joint
        angles, torso path.

        Returns numpy values: ``fitness``, ``speed_mps``, ``distance_m``, ``fell``,
        ``drift_deg``, ``fall_time``; ``quality`` (robots with a motor datasheet): the scalar
        energy / gait-quality metrics, ``rms_torque_frac`` {joint: RMS torque / nominal} and
        ``overheating`` (joints above 1); ``envelope`` (every robot): the actuator envelope of
        :func:`eaco_jax.gait.quality.envelope`; with ``record`` also ``time`` (T+1,), ``joints``
        {joint name: angles (T+1,)} for every actuated joint, ``torso_xyz`` (T+1, 3),
        ``torso_up`` (T+1, 3), ``controls`` (T, nu) (the commanded targets) and ``qpos``
        (T+1, nq) (the full configuration after each control step, for videos).
        """
        x = self.gait_row(params, "simulate")  # the bounds do not depend on backend or horizon
        if horizon is not None:
            check_horizon(float(horizon), self.spec)
        prob = self if backend is None and horizon is None else self.replace(
            backend=_resolve_backend(backend or self.backend),
            horizon=float(horizon if horizon is not None else self.horizon))
        quality = True  # the actuator envelope, for every robot
        controls = couple_controls(jax.jit(prob.controls)(x), prob.spec)
        # one gait: its sensitivity unjitted, as before (steering objects do not cross a jit)
        steer = prob.controls_and_steer(x)[1]
        if prob.backend == "mjx":
            run = jax.jit(lambda c: mjx_rollout(c, prob.spec, prob.slope_deg, prob.accuracy,
                                                quality=quality, record=True, impl=prob.impl,
                                                steer=steer))
            out = jax.tree.map(np.asarray, run(controls))
        else:
            out = native_rollout(np.asarray(controls), prob.spec, prob.slope_deg, prob.accuracy,
                                 quality=quality, record_qpos=True, steer=steer)
        trace, qpos = np.asarray(out["trace"]), np.asarray(out["qpos"])
        summary = prob.summarize(jnp.asarray(trace))
        metrics = gait_fitness(summary, prob.direction_deg, prob.turn)
        res: dict[str, Any] = {k: np.asarray(v)[0].item() for k, v in metrics.items()}
        res["fell"] = bool(res["fell"])
        res["fall_time"] = float(np.asarray(summary.fall_time)[0])
        res["backend"] = prob.backend
        res["horizon"] = prob.horizon
        q = prob._quality(jax.tree.map(jnp.asarray, out["acc"]), metrics["distance_m"], None, 1)
        if prob.spec.has_motors:
            res["quality"] = quality_record(q, prob.spec.joint_names)
        res["envelope"] = ql.envelope(q, prob.spec)
        if record:
            model = native_model(prob.spec, float(prob.slope_deg), prob.accuracy)
            res["time"] = np.arange(prob.n_steps + 1) * prob.spec.control_dt
            res["joints"] = {n: qpos[0, :, model.joint(n).qposadr[0]]
                             for n in prob.spec.joint_names}
            res["torso_xyz"] = trace[0, :, :3]
            res["torso_up"] = trace[0, :, 3:6]
            res["qpos"] = qpos[0]
            res["controls"] = np.asarray(controls)[0]
        return res

    def as_constrained(self):
        """The same problem as a :class:`~eaco_jax.problems.constrained.ConstrainedProblem`
        (objective ``-fitness`` of one vector, no constraints), for strategies that require one.

        Its batched ``evaluate`` is a vmap of the one-gait objective; on the native backend the
        callback still receives the whole colony at once. It is marked
        ``differentiable=False``, so ``minimize`` picks a colony without gradient steps.
        """
        from eaco_jax.problems.constrained import ConstrainedProblem

        def objective(x: jax.Array) -> jax.Array:
            x = jnp.clip(x.astype(self.dtype), self.lower, self.upper)
            fit = self.metrics(x[None])["fitness"][0]
            return -jnp.where(jnp.isfinite(fit), fit, 0.0).astype(self.dtype)

        return ConstrainedProblem(objective, lower=np.asarray(self.lower),
                                  upper=np.asarray(self.upper), name=self.name,
                                  differentiable=False)

    def params_dict(self, params: Any) -> dict[str, float]:
        """``{parameter name: value}`` of one parameter vector."""
        return {n: float(v) for n, v in zip(self.param_names, np.asarray(params).reshape(-1),
                                            strict=True)}


@struct.dataclass
class ConstrainedGaitProblem(GaitProblem):
    """Maximise speed (``f = -speed``) subject to the constraints of
    :mod:`eaco_jax.gait.constraints`, each from the same batched rollout over the R worlds;
    ``violation`` is the sum of their normalised excesses, so the colony's constraint handling
    (epsilon-constrained, Deb, penalty) applies as to any constrained problem.

    ``margin`` (search only): :meth:`evaluate` tightens the endurance, slip and drift
    constraints by this share of their scale (:func:`~eaco_jax.gait.constraints.with_margin`),
    since the worst of the search's R worlds understates the worst of many; ``report``,
    ``host_check``, the selection and the trials judge against the limits themselves."""

    margin: float = struct.field(pytree_node=False, default=0.0)

    @property
    def constrained(self) -> bool:
        return True

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return gc.names(self.turn)

    @property
    def num_inequality(self) -> int:
        return len(self.constraint_names)

    def constraints(self, solutions: jax.Array, worlds: Worlds | None = None
                    ) -> tuple[jax.Array, dict[str, jax.Array], jax.Array]:
        """Speed ``(m,)`` (m/s; turning gaits: deg/s, the fitness over the horizon, aggregated
        over the worlds like the fitness), each constraint's value ``{name: (m,)}`` and the
        normalised constraints ``g`` ``(m, p)`` of gaits ``(m, dim)`` in ``worlds`` (None: the
        nominal world)."""
        res = self.rollout(solutions, worlds, quality=True)
        per_world = res["fitness"] / self.horizon
        if worlds is None:
            speed = per_world[:, 0]
        else:
            cfg = self.robust or RobustConfig()
            speed = aggregate(per_world, cfg.aggregate, cfg.alpha)
        vals = gc.values(res, self.turn)
        g = gc.normalised(vals, ql.mo.motor_model(self.spec), self.horizon,
                          1 if worlds is None else worlds.size)
        return speed, vals, g

    def colony_in_worlds(self, solutions: jax.Array,
                         key: jax.Array | None) -> tuple[jax.Array, Worlds | None]:
        """A colony ``(m, dim)`` checked and clipped to the box, and the worlds ``key`` picks
        from the optimisation stream (key-less: its batch 0; None without ``robust``)."""
        if solutions.ndim != 2 or solutions.shape[-1] != self.dim:
            raise ProblemError(
                f"gait problem {self.name!r}: solutions must be (ants, {self.dim}), "
                f"got {tuple(solutions.shape)}")
        x = jnp.clip(solutions.astype(self.dtype), self.lower, self.upper)
        worlds = None
        if self.robust is not None:
            worlds = self.worlds(None if key is None else optimisation_key(self.robust.seed, key))
        return x, worlds

    def evaluate(self, solutions: jax.Array, key: jax.Array | None = None) -> Evaluation:
        """``Evaluation(f=-speed, violation)`` of a colony ``(m, dim)`` in the worlds ``key``
        picks from the optimisation stream (see :class:`GaitProblem`)."""
        x, worlds = self.colony_in_worlds(solutions, key)
        speed, _, g = self.constraints(x, worlds)
        g = gc.with_margin(g, self.margin, self.constraint_names)
        speed = jnp.where(jnp.isfinite(speed), speed, 0.0).astype(self.dtype)
        return Evaluation(f=-speed, violation=gc.violation(g).astype(self.dtype))

    def report(self, params: Any, worlds: Worlds | None = None) -> dict[str, Any]:
        """One gait's ``speed``, ``violation``, ``feasible`` and per constraint its value,
        limit, margin and whether it holds (:func:`eaco_jax.gait.constraints.table`), in
        ``worlds`` (None: the nominal world)."""
        x = self.gait_row(params)
        speed, vals, g = jax.jit(self.constraints)(x, worlds)
        v = float(np.asarray(gc.violation(g))[0])
        return {"speed": float(np.asarray(speed)[0]), "violation": v, "feasible": v <= 0.0,
                "worlds": 1 if worlds is None else worlds.size,
                "constraints": gc.table({k: np.asarray(a)[0] for k, a in vals.items()},
                                        np.asarray(g)[0], ql.mo.motor_model(self.spec),
                                        self.horizon, 1 if worlds is None else worlds.size)}

    def host_check(self, x: Any) -> dict[str, Any]:
        """The returned best re-simulated in the key-less worlds (the optimisation stream's
        batch 0; the nominal world without ``robust``): ``f`` (-speed), ``violation``,
        ``feasible``, ``cost`` (``f`` if feasible, else +inf) and ``constraints`` (each one's
        value, limit, margin and whether it holds). A point outside the bounds raises
        :class:`ProblemError`."""
        point = np.asarray(x, np.float64).reshape(-1)
        lo, hi = np.asarray(self.lower, np.float64), np.asarray(self.upper, np.float64)
        if point.shape != lo.shape:
            raise ProblemError(f"problem {self.name!r}: a point must have shape {lo.shape}, "
                               f"got {point.shape}")
        slack = 4 * np.finfo(np.float32).eps * np.maximum(np.abs(lo), 1.0)
        if np.any(point < lo - slack) or np.any(point > hi + slack):
            raise ProblemError(f"problem {self.name!r}: point outside its bounds")
        rep = self.report(point, self.worlds() if self.robust is not None else None)
        f = -rep["speed"]
        return {"f": f, "violation": rep["violation"], "feasible": rep["feasible"],
                "cost": f if rep["feasible"] else math.inf,
                "tolerance": {"inequality": 0.0, "equality": 0.0},
                "constraints": rep["constraints"]}


def body_frame_speeds(trace: jax.Array, dt: float, fall_time: jax.Array
                      ) -> tuple[jax.Array, jax.Array]:
    """Mean forward and lateral speed ``(...)`` (m/s, + = forward / left) of torso traces
    ``(..., T + 1, 7)``: each control step's horizontal displacement projected on the torso's
    heading at the step's start, summed until the fall (``fall_time``, s; the horizon when it
    did not fall), over the time walked; a unicycle's ``v`` (and the sideways drift) whatever
    the turn. Non-finite traces give 0."""
    finite = jnp.all(jnp.isfinite(trace), axis=(-1, -2))
    tr = jnp.nan_to_num(trace, nan=0.0, posinf=0.0, neginf=0.0)
    step = jnp.diff(tr[..., :2], axis=-2)
    yaw = tr[..., :-1, 6]
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    fwd = step[..., 0] * c + step[..., 1] * s
    lat = -step[..., 0] * s + step[..., 1] * c
    n = jnp.round(fall_time / dt).astype(jnp.int32)
    upto = jnp.arange(step.shape[-2]) < n[..., None]
    walked = jnp.maximum(n.astype(jnp.float32) * dt, 1e-6)
    f = jnp.where(finite, jnp.sum(jnp.where(upto, fwd, 0.0), -1) / walked, 0.0)
    lt = jnp.where(finite, jnp.sum(jnp.where(upto, lat, 0.0), -1) / walked, 0.0)
    return f, lt


_FITNESS_KEYS = ("fitness", "distance_m", "speed_mps", "fell", "drift_deg", "fall_time",
                 "turn_deg_s")


def quality_record(q: dict, joint_names) -> dict[str, Any]:
    """JSON-ready quality metrics of one gait (``q``: :func:`~eaco_jax.gait.quality.finalize`
    output with a leading axis of 1): scalars, RMS torque fraction per joint, overheating."""
    rec: dict[str, Any] = {k: float(np.asarray(q[k]).reshape(-1)[0]) for k in QUALITY_SCALARS}
    rms = np.asarray(q["rms_torque_frac"]).reshape(-1, len(joint_names))[0]
    rec["rms_torque_frac"] = {n: float(v) for n, v in zip(joint_names, rms, strict=True)}
    rec["overheating"] = ql.overheating(rms, joint_names)
    if "endurance_min" in q:
        rec.update({k: float(np.asarray(q[k]).reshape(-1)[0]) for k in MOTOR_SCALARS})
        rec["motors"] = motor_table(q, joint_names)
    return rec


MOTOR_SCALARS = ("electrical_energy_j", "mean_electrical_power_w", "electrical_cot",
                 "min_endurance_min", "peak_current_max_frac")
MOTOR_COLUMNS = ("rms_current_frac", "peak_current_frac", "copper_loss_w", "winding_end_c",
                 "winding_ripple_c", "winding_10min_c", "winding_steady_c", "endurance_min")


def motor_table(q: dict, joint_names) -> dict[str, dict[str, float | None]]:
    """Per joint electrical and thermal figures of one gait (``q`` with a leading axis of 1):
    :data:`MOTOR_COLUMNS`; an endless endurance is None (JSON has no infinity)."""
    cols = {c: np.asarray(q[c]).reshape(-1, len(joint_names))[0] for c in MOTOR_COLUMNS}
    return {n: {c: (float(v[j]) if np.isfinite(v[j]) else None) for c, v in cols.items()}
            for j, n in enumerate(joint_names)}


def _resolve_backend(backend: str) -> str:
    if backend not in BACKENDS:
        raise ProblemError(f"unknown backend {backend!r}; use one of {', '.join(BACKENDS)}")
    if backend == "auto":
        return "native" if jax.default_backend() == "cpu" else "mjx"
    if backend == "native":
        try:
            jax.devices("cpu")
        except (RuntimeError, AssertionError) as err:  # jax raises either, by version
            raise ProblemError(
                "the native backend runs MuJoCo on the host CPU through jax.pure_callback, "
                "which needs JAX's cpu platform, but JAX_PLATFORMS="
                f"{os.environ.get('JAX_PLATFORMS', '')!r} leaves it out: set "
                "JAX_PLATFORMS=cuda,cpu (or unset it), or use --backend mjx") from err
    return backend


#: most control steps a horizon may hold: the walk engine's clock is ``arange(n, float32) * dt``
#: (exact step indices up to 2**24; past 2**31 the int32 step counter overflows and XLA aborts)
MAX_CONTROL_STEPS = 2**24


def check_horizon(horizon: float, spec: RobotSpec) -> None:
    """Refuse a horizon shorter than one control step or longer than the step clock counts
    exactly (one :class:`ProblemError` line naming the allowed range), before any simulation."""
    if horizon < spec.control_dt:
        raise ProblemError(f"horizon must be at least one control step ({spec.control_dt} s)")
    steps = horizon / spec.control_dt
    if steps > MAX_CONTROL_STEPS:
        most = math.floor(MAX_CONTROL_STEPS * spec.control_dt)
        raise ProblemError(
            f"horizon {horizon:g} s is {steps:.3g} control steps of {spec.control_dt} s, more "
            f"than the {MAX_CONTROL_STEPS} the step clock counts exactly; use a horizon of at "
            f"most {most} s")


def make_gait_problem(
    robot: str | RobotSpec = "nao",
    backend: str = "auto",
    horizon: float = 20.0,
    direction_deg: float = 0.0,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
    robust: RobustConfig | None = None,
    penalty: str | None = None,
    penalty_weight: float = 0.0,
    impl: str = "auto",
    turn: str | None = None,
    constrained: bool = False,
    ik: str = "auto",
    steering: Steering | None = None,
    margin: float = 0.0,
) -> GaitProblem:
    """A :class:`GaitProblem` for a robot (a shipped one's name: "nao", "ant", ..., or the path
    of a spec .json, see docs/robots.md) and backend ("auto", "mjx",
    "native"); the horizon in seconds, the desired walking direction and floor slope in degrees;
    ``robust`` for fitness over randomised worlds, ``penalty`` ("power" | "cot") and its weight
    for an energy-aware fitness; ``turn`` ("left" | "right") scores the heading turned instead
    of the distance; ``impl`` the MJX implementation ("jax", "warp" = MuJoCo Warp on
    CUDA, "auto" = warp where it can run); ``constrained`` maximises speed under the
    constraints of :mod:`eaco_jax.gait.constraints` (a :class:`ConstrainedGaitProblem`);
    ``ik`` the biped's leg IK (:func:`~eaco_jax.gait.walk_engine.uses_analytic_ik`: "auto",
    "analytic" needs the NAO's leg geometry, "generic" works on any leg chain); ``steering``
    the heading controller of :mod:`eaco_jax.gait.steer` (a walking biped only); ``margin``
    the constrained search's margin (:class:`ConstrainedGaitProblem`)."""
    if isinstance(robot, RobotSpec):
        spec = robot
    else:
        try:
            spec = load_robot(robot)
        except ValueError as err:
            raise ProblemError(str(err)) from None
    backend = _resolve_backend(backend)
    for label, v in (("horizon", horizon), ("direction_deg", direction_deg),
                     ("slope_deg", slope_deg), ("penalty_weight", penalty_weight)):
        if not isinstance(v, int | float) or not math.isfinite(v):
            raise ProblemError(f"{label} must be a finite number, got {v!r}")
    check_horizon(horizon, spec)
    if abs(slope_deg) >= 45.0:
        raise ProblemError(f"slope_deg must be within (-45, 45) degrees, got {slope_deg}")
    if accuracy not in ("fast", "accurate"):
        raise ProblemError(f"accuracy must be 'fast' or 'accurate', got {accuracy!r}")
    if robust is not None and not isinstance(robust, RobustConfig):
        raise ProblemError(f"robust must be a RobustConfig, got {type(robust).__name__}")
    if turn not in TURNS:
        raise ProblemError(f"turn must be None, 'left' or 'right', got {turn!r}")
    if penalty not in PENALTIES:
        raise ProblemError(f"penalty must be None, 'power' or 'cot', got {penalty!r}")
    if penalty_weight < 0:
        raise ProblemError(f"penalty_weight must be >= 0, got {penalty_weight}")
    if penalty is not None and not spec.has_motors:
        raise ProblemError(f"robot {spec.name!r} has no motor datasheet: the energy penalty "
                           "needs one (nao, op3, go2)")
    if not isinstance(constrained, bool):
        raise ProblemError(f"constrained must be True or False, got {constrained!r}")
    if constrained and ql.mo.motor_model(spec) is None:
        raise ProblemError(f"robot {spec.name!r} has no electrical motor data (a spec "
                           "'motors' block with supply_voltage_v): no constrained gait search")
    if constrained and penalty is not None:
        raise ProblemError("a constrained gait search has no energy penalty: drop penalty "
                           "(the constraints replace it)")
    impl = _resolve_impl(impl, backend)
    if spec.gait == "biped":
        uses_analytic_ik(spec, ik)  # a ConfigError line for an unknown or unusable choice
    elif ik not in IK_CHOICES:
        raise ProblemError(f"ik must be one of {', '.join(IK_CHOICES)}, got {ik!r}")
    if steering is not None:
        if not isinstance(steering, Steering):
            raise ProblemError(f"steering must be a Steering, got {type(steering).__name__}")
        if spec.gait != "biped":
            raise ProblemError(f"steering needs a biped's walk engine (a turn rate); robot "
                               f"{spec.name!r} is a {spec.gait}: drop steering")
        if turn is not None and not steering.track_turn:
            raise ProblemError("a turning gait has no heading to hold: drop steering (--steer) "
                               "or turn, or track its own turn (--track-turn; in the API "
                               "Steering(track_turn=True))")
    if not (isinstance(margin, int | float) and math.isfinite(margin) and 0 <= margin < 1):
        raise ProblemError(f"margin must be a number in [0, 1), got {margin!r}")
    if margin and not constrained:
        raise ProblemError("margin tightens a constrained search: add constrained=True")
    lo, hi = bounds(spec, ik)
    name = f"gait-{spec.name}"
    extra = {"margin": float(margin)} if constrained else {}
    cls = ConstrainedGaitProblem if constrained else GaitProblem
    return cls(
        lower=jnp.asarray(lo), upper=jnp.asarray(hi), spec=spec, backend=backend,
        horizon=float(horizon), direction_deg=float(direction_deg), slope_deg=float(slope_deg),
        accuracy=accuracy, name=name, robust=robust, penalty=penalty,
        penalty_weight=float(penalty_weight), impl=impl, turn=turn, ik=ik, steering=steering,
        **extra)


IMPLS = ("auto", "jax", "warp")


def _resolve_impl(impl: str, backend: str) -> str:
    """``auto`` -> warp on a CUDA device where warp-lang imports, else jax."""
    from eaco_jax.gait.mjx_import import warp_usable

    if impl not in IMPLS:
        raise ProblemError(f"impl must be one of {', '.join(IMPLS)}, got {impl!r}")
    if backend != "mjx":
        return "jax"
    if impl == "auto":
        return "warp" if warp_usable() else "jax"
    if impl == "warp" and not warp_usable():
        raise ProblemError("impl 'warp' needs a CUDA GPU and warp-lang "
                           "(pip install 'eaco-jax[gpu]'); use impl='jax'")
    return impl


__all__ = ["BACKENDS", "ConstrainedGaitProblem", "GaitProblem", "RobustConfig", "known_robots",
           "body_frame_speeds", "make_gait_problem", "quality_record"]
