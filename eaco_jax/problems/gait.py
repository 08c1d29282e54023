"""Gait optimisation as a continuous problem: each ant is a walk-engine parameter vector.

``GaitProblem.evaluate(X)`` rolls the whole colony out as one batched simulation (MJX, or
MuJoCo's C engine through a ``jax.pure_callback``) and returns ``f = -fitness`` (the paper's
distance-based gait fitness, :mod:`eaco_jax.gait.fitness`; minimised, so lower is better) with
zero violation. ``backend="auto"`` picks ``"mjx"`` on GPU/TPU and ``"native"`` on CPU, where the
C engine is an order of magnitude faster. ``simulate(params)`` re-runs one gait and returns what
plots and reports need (time, joint angles, torso trajectory, speed, distance, fall, drift).
"""

from __future__ import annotations

import math
import os
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.gait.fitness import GaitSummary, gait_fitness, summarize
from eaco_jax.gait.rollout_mjx import mjx_trace
from eaco_jax.gait.rollout_native import native_model, native_trace, native_trace_callback
from eaco_jax.gait.walk_engine import bounds, control_sequence, param_names
from eaco_jax.problems.base import Evaluation, ProblemError
from eaco_jax.robots import RobotSpec, known_robots, load_robot

BACKENDS = ("auto", "mjx", "native")


@struct.dataclass
class GaitProblem:
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

    kind = "continuous"
    differentiable = False  # a simulation: no gradient repair / refinement steps

    @property
    def dim(self) -> int:
        return int(self.lower.shape[-1])

    @property
    def dtype(self) -> Any:
        return self.lower.dtype

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
            p, self.n_steps, self.spec, heading, self.slope_deg))(solutions)

    def trace(self, solutions: jax.Array) -> jax.Array:
        """Torso traces ``(m, n_steps + 1, 6)`` of gaits ``(m, dim)`` on this backend."""
        controls = self.controls(solutions)
        if self.backend == "mjx":
            return mjx_trace(controls, self.spec, self.slope_deg, self.accuracy)
        return native_trace_callback(controls, self.spec, self.slope_deg, self.accuracy)

    def summarize(self, trace: jax.Array) -> GaitSummary:
        return summarize(trace[..., :3], trace[..., 3:], self.spec.control_dt,
                         self.spec.fall_height, self.spec.fall_tilt_deg, self.slope_deg)

    def metrics(self, solutions: jax.Array) -> dict[str, jax.Array]:
        """Fitness, distance_m, speed_mps, fell, drift_deg of each gait ``(m, dim)``."""
        return gait_fitness(self.summarize(self.trace(solutions)), self.direction_deg)

    def evaluate(self, solutions: jax.Array) -> Evaluation:
        """``Evaluation(f=-fitness, violation=0)`` for a colony ``(m, dim)``."""
        if solutions.ndim != 2 or solutions.shape[-1] != self.dim:
            raise ProblemError(
                f"gait problem {self.name!r}: solutions must be (ants, {self.dim}), "
                f"got {tuple(solutions.shape)}")
        x = jnp.clip(solutions.astype(self.dtype), self.lower, self.upper)
        fit = self.metrics(x)["fitness"]
        fit = jnp.where(jnp.isfinite(fit), fit, 0.0).astype(self.dtype)
        return Evaluation(f=-fit, violation=jnp.zeros_like(fit))

    def simulate(
        self, params: Any, record: bool = True, backend: str | None = None,
        horizon: float | None = None,
    ) -> dict[str, Any]:
        """Re-simulate one gait; metrics plus (if ``record``) time, joint angles, torso path.

        Returns numpy values: ``fitness``, ``speed_mps``, ``distance_m``, ``fell``,
        ``drift_deg``, ``fall_time``; with ``record`` also ``time`` (T+1,), ``joints``
        {joint name: angles (T+1,)} for every actuated joint, ``torso_xyz`` (T+1, 3),
        ``torso_up`` (T+1, 3), ``controls`` (T, nu) (the commanded targets) and ``qpos``
        (T+1, nq) (the full configuration after each control step, for videos).
        """
        p = np.asarray(params, np.float32).reshape(-1)
        if p.shape != (self.dim,) or not np.all(np.isfinite(p)):
            raise ProblemError(f"simulate needs {self.dim} finite parameters, got {p.shape}")
        prob = self if backend is None and horizon is None else self.replace(
            backend=_resolve_backend(backend or self.backend),
            horizon=float(horizon if horizon is not None else self.horizon))
        x = jnp.clip(jnp.asarray(p)[None], prob.lower, prob.upper)
        controls = jax.jit(prob.controls)(x)
        if prob.backend == "mjx":
            run = jax.jit(lambda c: mjx_trace(c, prob.spec, prob.slope_deg, prob.accuracy,
                                              record=True))
            trace, qpos = (np.asarray(a) for a in run(controls))
        else:
            trace, qpos = native_trace(np.asarray(controls), prob.spec, prob.slope_deg,
                                       prob.accuracy, record_qpos=True)
        metrics = gait_fitness(prob.summarize(jnp.asarray(trace)), prob.direction_deg)
        out: dict[str, Any] = {k: np.asarray(v)[0].item() for k, v in metrics.items()}
        out["fell"] = bool(out["fell"])
        out["fall_time"] = float(np.asarray(prob.summarize(jnp.asarray(trace)).fall_time)[0])
        out["backend"] = prob.backend
        out["horizon"] = prob.horizon
        if record:
            model = native_model(prob.spec, float(prob.slope_deg), prob.accuracy)
            out["time"] = np.arange(prob.n_steps + 1) * prob.spec.control_dt
            out["joints"] = {n: qpos[0, :, model.joint(n).qposadr[0]]
                             for n in prob.spec.joint_names}
            out["torso_xyz"] = trace[0, :, :3]
            out["torso_up"] = trace[0, :, 3:]
            out["qpos"] = qpos[0]
            out["controls"] = np.asarray(controls)[0]
        return out

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


def make_gait_problem(
    robot: str | RobotSpec = "nao",
    backend: str = "auto",
    horizon: float = 20.0,
    direction_deg: float = 0.0,
    slope_deg: float = 0.0,
    accuracy: str = "fast",
) -> GaitProblem:
    """A :class:`GaitProblem` for a known robot ("nao", "ant") and backend ("auto", "mjx",
    "native"); the horizon in seconds, the desired walking direction and floor slope in degrees."""
    if isinstance(robot, RobotSpec):
        spec = robot
    else:
        try:
            spec = load_robot(robot)
        except ValueError as err:
            raise ProblemError(str(err)) from None
    backend = _resolve_backend(backend)
    for label, v in (("horizon", horizon), ("direction_deg", direction_deg),
                     ("slope_deg", slope_deg)):
        if not isinstance(v, int | float) or not math.isfinite(v):
            raise ProblemError(f"{label} must be a finite number, got {v!r}")
    if horizon < spec.control_dt:
        raise ProblemError(f"horizon must be at least one control step ({spec.control_dt} s)")
    if abs(slope_deg) >= 45.0:
        raise ProblemError(f"slope_deg must be within (-45, 45) degrees, got {slope_deg}")
    if accuracy not in ("fast", "accurate"):
        raise ProblemError(f"accuracy must be 'fast' or 'accurate', got {accuracy!r}")
    lo, hi = bounds(spec)
    name = f"gait-{spec.name}"
    return GaitProblem(
        lower=jnp.asarray(lo), upper=jnp.asarray(hi), spec=spec, backend=backend,
        horizon=float(horizon), direction_deg=float(direction_deg), slope_deg=float(slope_deg),
        accuracy=accuracy, name=name)


__all__ = ["BACKENDS", "GaitProblem", "known_robots", "make_gait_problem"]
