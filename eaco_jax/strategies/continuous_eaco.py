"""Continuous EACO: an elitist, mutated, archive-based ant colony for constrained real problems.

Our reading of the paper for real vectors (PAPER_NOTES.md section 2):

* **Pheromone = ranked archive** (ACO_R, Socha & Dorigo 2008, EJOR 185:1155-1173): ``k``
  solutions sorted best first by the selected constraint-handling order
  (:mod:`eaco_jax.ops.constraints`). Rank ``l`` has weight ``exp(-l^2 / (2 (q k)^2))``.
* **Construction**: with probability ``q0`` (the paper's exploitation parameter) an ant is
  guided by the archive's best, otherwise by a rank-weighted guide; each coordinate is drawn from
  a Gaussian around the guide with width ``rho * mean |x_e - x_guide|`` over the archive (``rho``
  is ACO_R's xi: pheromone evaporation = how fast the width shrinks).
* **Mutated**: with probability ``p_crossover`` an ant is the Laplace-crossover child of its
  guide and a second rank-weighted archive member; with probability ``p_mutation`` it then
  undergoes power mutation (Deep & Thakur 2007, :mod:`eaco_jax.ops.real_ops`).
* **Chaos**: each ant carries a logistic-map sequence z <- 4z(1-z); while the best has not
  improved for ``chaos_patience`` iterations, a fraction ``chaos_rate`` of ants is placed at
  ``best + chaos_strength * (2z - 1) * (upper - lower)`` to escape stagnation.
* **Elitist**: the archive is the best ``k`` of archive + colony, so the best always survive.
* **Gradient repair** (``repair_steps``): infeasible ants take Newton steps on their violated
  constraints, with Jacobians from ``jax.jacobian``
  (:func:`eaco_jax.ops.constraints.gradient_repair`).
* **Local refinement** (``refine_ants``): the last ants of each colony are SQP-style steps from
  the archive's best (Newton on the KKT conditions of its active constraints, with the
  Lagrangian Hessian from autodiff, at step lengths 1, 1/4, 1/16, ...;
  :func:`eaco_jax.ops.constraints.sqp_direction`). They are ordinary ants:
  evaluated by the driver and kept only if the archive order says they are better.
* Bounds are exact: every ant is clipped to ``[lower, upper]`` after every operator.

Evaluation accounting: every point whose objective/constraints are computed costs one
evaluation: the driver's colony (``num_ants``), the initial archive (``archive_size``), each
repair step (1 per step per ant) and the refinement's derivatives (``dim + 1`` per iteration,
what a finite-difference gradient would cost; autodiff Hessians are charged the same), and a
chaotic restart (``archive_size``). ``minimize(max_evaluations=N)`` is a hard cap on this
count: the driver starts an iteration only if its worst case (:meth:`ContinuousEACO.max_charge`)
fits in what is left. ``state.evaluations`` has the charged count and
``state.target_evaluations`` the count at which f - f* <= 1e-4 was first met.

Finite-difference accounting (what the gradient modes would cost without autodiff), kept
beside it: ``fd_evaluations`` charges one evaluation per point at which the objective and all
constraints are computed (the CEC2006 unit): a repair step n + 1 (its point and a forward-
difference Jacobian), a refinement (n + 1)(n + 2) / 2 (a forward-difference Hessian, whose
points also give the gradients); ``fd_function_evaluations`` charges every function apart:
n + 1 per gradient per function (the objective and each of the p + q constraints) and
(n + 1)(n + 2) / 2 per Hessian per function. Both add the colony's ants; ``target_fd_*`` are
their counts when the target was first met. Derivative-free (``repair_steps = refine_ants =
0``) all three counts are equal.

Precision: the colony works in the problem's dtype (float64 when the problem was built inside
:func:`eaco_jax.problems.float64`); ``best_cost`` (float32, the driver's field) is the best
feasible objective, +inf until a feasible point is found; ``best_f`` keeps full precision.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.ops import constraints as ch
from eaco_jax.ops.chaos import logistic_step
from eaco_jax.ops.real_ops import laplace_crossover_sample, power_mutation_sample
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import (
    AT_LEAST_ONE,
    NONNEG,
    POSITIVE,
    UNIT,
    Range,
    State,
    Strategy,
    as_params,
    base_fields,
    replacement_slots,
)

Array = jax.Array

#: success rule of CEC2006: feasible and f - f* <= this
TARGET_TOLERANCE = 1e-4


@struct.dataclass
class ContinuousParams:
    """Traced hyper-parameters (vmappable for sweeps such as the paper's Table 3)."""

    q0: Array = 0.5  # fraction of ants guided by the archive's best (exploitation)
    rho: Array = 0.6  # ACO_R xi: Gaussian width = rho * archive spread around the guide
    locality: Array = 0.2  # ACO_R q: rank-weight locality (small -> greedy on top ranks)
    p_crossover: Array = 0.3  # probability an ant is a Laplace-crossover child
    p_mutation: Array = 0.2  # probability an ant is power-mutated
    laplace_a: Array = 0.0  # Laplace crossover location a
    laplace_b: Array = 0.15  # Laplace crossover scale b
    power_index: Array = 10.0  # power mutation index p
    penalty: Array = 0.3  # PEN of the static penalty method
    eps_fraction: Array = 0.2  # eps(0) = violation at this quantile of the initial archive
    eps_cutoff: Array = 50.0  # Tc: iterations after which eps = 0
    eps_exponent: Array = 5.0  # cp of the epsilon schedule
    chaos_rate: Array = 0.1  # fraction of ants placed by the chaotic map while stagnating
    chaos_strength: Array = 0.05  # chaotic displacement, as a fraction of the box width
    chaos_patience: Array = 20.0  # iterations without improvement before chaos acts
    restart_patience: Array = 100.0  # stagnation before a chaotic restart of the archive
    p_repair: Array = 1.0  # probability an infeasible ant gets gradient repair
    repair_margin: Array = 1e-10  # repair aims this far inside (fraction of mean box width)
    refine_active: Array = 1e-3  # inequality counts as active within this distance (box frac.)

    #: documented ranges, checked on the host before a run (concrete values only)
    RANGES: ClassVar[dict[str, Range]] = {
        "q0": UNIT, "rho": POSITIVE, "locality": POSITIVE, "p_crossover": UNIT,
        "p_mutation": UNIT, "laplace_a": Range(), "laplace_b": POSITIVE,
        "power_index": POSITIVE, "penalty": NONNEG, "eps_fraction": UNIT,
        "eps_cutoff": POSITIVE, "eps_exponent": POSITIVE, "chaos_rate": UNIT,
        "chaos_strength": NONNEG, "chaos_patience": NONNEG, "restart_patience": AT_LEAST_ONE,
        "p_repair": UNIT, "repair_margin": NONNEG, "refine_active": NONNEG,
    }


@struct.dataclass
class ContinuousState(State):
    archive_x: Array  # (k, n) ranked archive (the pheromone); unevaluated entries have f = inf
    archive_f: Array
    archive_v: Array
    epsilon0: Array
    epsilon: Array
    chaos: Array
    archive_chaos: Array
    best_f: Array
    best_violation: Array
    target_evaluations: Array
    target_iteration: Array
    fd_evaluations: Array  # finite-difference accounting, point unit (module docstring)
    fd_function_evaluations: Array  # ... every function charged apart
    target_fd_evaluations: Array
    target_fd_function_evaluations: Array


@dataclasses.dataclass(frozen=True)
class ContinuousEACO(Strategy):
    """Elitist-mutated continuous ant colony with constraint handling (see module docstring)."""

    num_ants: int = 20
    archive_size: int = 30
    constraint_method: str = "epsilon"
    repair_steps: int = 3
    refine_ants: int = 4
    problem_kind: ClassVar[str] = "continuous"

    def __post_init__(self) -> None:
        ch.check_method(self.constraint_method)
        if self.num_ants < 1 or self.archive_size < 2:
            raise ConfigError("ContinuousEACO needs num_ants >= 1 and archive_size >= 2")
        if not 0 <= self.refine_ants <= self.num_ants:
            raise ConfigError(f"refine_ants must be in [0, num_ants={self.num_ants}]")
        if self.repair_steps < 0:
            raise ConfigError("repair_steps must be >= 0")

    def default_params(self, problem: Any = None) -> ContinuousParams:
        return ContinuousParams()

    def max_charge(self, problem: Any = None) -> int:
        """One colony, the refinement's ``dim + 1`` and every repair step of every ant."""
        n = int(getattr(problem, "dim", 0))
        extra = n + 1 if self.refine_ants > 0 else 0
        if self.repair_steps > 0 and problem is not None and _num_constraints(problem) > 0:
            extra += self.repair_steps * self.num_ants
        return self.num_ants + extra

    def charge_note(self, problem: Any = None) -> str:
        parts = [f"{self.num_ants} ants"]
        if self.refine_ants > 0:
            parts.append(f"refinement dim + 1 = {int(getattr(problem, 'dim', 0)) + 1}")
        if self.repair_steps > 0 and problem is not None and _num_constraints(problem) > 0:
            parts.append(f"repair up to {self.repair_steps} x {self.num_ants}")
        return " + ".join(parts)

    def inactive_params(self, params: ContinuousParams) -> dict[str, str]:
        """Fields without effect under these switches -> the switch that makes them act."""

        def positive(name: str) -> bool:
            return bool(jnp.all(jnp.asarray(getattr(params, name)) > 0))

        dead: dict[str, str] = {}
        rules = (
            (("eps_fraction", "eps_cutoff", "eps_exponent"),
             self.constraint_method == "epsilon", "constraint_method='epsilon'"),
            (("penalty",), self.constraint_method == "penalty", "constraint_method='penalty'"),
            (("p_repair",), self.repair_steps > 0, "repair_steps > 0"),
            (("repair_margin",), self.repair_steps > 0 or self.refine_ants > 0,
             "repair_steps > 0 or refine_ants > 0"),
            (("refine_active",), self.refine_ants > 0, "refine_ants > 0"),
            (("laplace_a", "laplace_b"), positive("p_crossover"), "p_crossover > 0"),
            (("power_index",), positive("p_mutation"), "p_mutation > 0"),
        )
        for names, active, switch in rules:
            if not active:
                dead.update(dict.fromkeys(names, switch))
        return dead

    # ----------------------------------------------------------------- helpers
    def _order(self, f: Array, v: Array, params: ContinuousParams, eps: Array) -> Array:
        return ch.rank_order(f, v, self.constraint_method, eps, params.penalty)

    def prepare(self, problem: Any) -> Any:
        """Check that ``problem`` is continuous (box bounds, ``evaluate`` -> Evaluation) and
        that the gradient modes in use can differentiate it."""
        if getattr(problem, "kind", None) != "continuous" or not hasattr(problem, "lower"):
            raise ProblemError(
                "ContinuousEACO needs a continuous problem with box bounds (an "
                "eaco_jax.problems.ConstrainedProblem, a gait problem, ...), got "
                f"{type(problem).__name__}")
        constrained = _num_constraints(problem) > 0
        if not getattr(problem, "differentiable", True) and (
            self.refine_ants or (self.repair_steps and constrained)
        ):
            raise ConfigError(
                f"{problem.name!r} is not differentiable (a simulation); use "
                "ContinuousEACO(refine_ants=0, repair_steps=0)"
            )
        return problem

    # ----------------------------------------------------------------- init
    def _init(self, key: Array, problem: Any, params: ContinuousParams) -> ContinuousState:
        """Archive members drawn uniformly in the box, not evaluated (f = violation = +inf):
        the colony's first ants replace them, and epsilon(0) is set at the first ``tell``."""
        dtype = problem.dtype
        params = as_params(params, dtype)
        k_arch, k_chaos, k_arch2, k_run = jax.random.split(key, 4)
        lo, hi = problem.lower, problem.upper
        x = lo + (hi - lo) * jax.random.uniform(k_arch, (self.archive_size, problem.dim), dtype)
        inf = jnp.full((self.archive_size,), jnp.inf, dtype)
        return ContinuousState(
            **base_fields(k_run, params, x[0]),
            archive_x=x,
            archive_f=inf,
            archive_v=inf,
            epsilon0=jnp.zeros((), dtype),
            epsilon=jnp.zeros((), dtype),
            chaos=jax.random.uniform(k_chaos, (self.num_ants, problem.dim), dtype, 0.01, 0.99),
            archive_chaos=jax.random.uniform(
                k_arch2, (self.archive_size, problem.dim), dtype, 0.01, 0.99),
            best_f=jnp.asarray(jnp.inf, dtype),
            best_violation=jnp.asarray(jnp.inf, dtype),
            target_evaluations=jnp.asarray(-1, jnp.int32),
            target_iteration=jnp.asarray(-1, jnp.int32),
            fd_evaluations=jnp.zeros((), jnp.int32),
            fd_function_evaluations=jnp.zeros((), jnp.int32),
            target_fd_evaluations=jnp.asarray(-1, jnp.int32),
            target_fd_function_evaluations=jnp.asarray(-1, jnp.int32),
        )

    # ----------------------------------------------------------------- ask
    def _ask(
        self, key: Array, state: ContinuousState, problem: Any
    ) -> tuple[Array, ContinuousState]:
        p = state.params
        lo, hi = problem.lower, problem.upper
        m, k, n = self.num_ants, self.archive_size, problem.dim
        dtype = problem.dtype
        state = self._chaotic_restart(state, problem)
        arch = state.archive_x
        keys = jax.random.split(key, 10)

        # guides: best with probability q0, else by rank weight (ACO_R)
        ranks = jnp.arange(k, dtype=dtype)
        logw = -(ranks**2) / (2.0 * (p.locality * k) ** 2)
        greedy = jax.random.uniform(keys[0], (m,), dtype) < p.q0
        guide = jnp.where(greedy, 0, jax.random.categorical(keys[1], logw, shape=(m,)))
        partner = jax.random.categorical(keys[2], logw, shape=(m,))
        xg = arch[guide]

        # Gaussian sampling, width from the archive spread around the guide
        spread = jnp.mean(jnp.abs(arch[None, :, :] - xg[:, None, :]), axis=1) * k / (k - 1)
        sigma = jnp.maximum(p.rho * spread, 1e-12 * (hi - lo))
        x = jnp.clip(xg + sigma * jax.random.normal(keys[3], (m, n), dtype), lo, hi)

        # Laplace crossover of guide and partner (one of the two offspring, at random)
        ck = jax.random.split(keys[4], m)
        y1, y2 = jax.vmap(lambda kk, a, b: laplace_crossover_sample(
            kk, a, b, lo, hi, p.laplace_a, p.laplace_b))(ck, xg, arch[partner])
        pick = jax.random.bernoulli(keys[5], 0.5, (m, 1))
        child = jnp.where(pick, y1, y2)
        do_cross = jax.random.uniform(keys[6], (m, 1), dtype) < p.p_crossover
        x = jnp.where(do_cross, child, x)

        # power mutation: mutated ants change each coordinate w.p. 1/n (at least one)
        mk = jax.random.split(keys[7], 3)
        mutated = jax.vmap(lambda kk, a: power_mutation_sample(kk, a, lo, hi, p.power_index))(
            jax.random.split(mk[0], m), x)
        coord = (jax.random.uniform(mk[1], (m, n), dtype) < 1.0 / n) | (
            jnp.arange(n)[None, :] == jax.random.randint(mk[2], (m, 1), 0, n))
        do_mut = jax.random.uniform(keys[8], (m, 1), dtype) < p.p_mutation
        x = jnp.where(do_mut & coord, mutated, x)

        # chaos perturbation around the best while stagnating (logistic map per ant/coordinate)
        z = logistic_step(state.chaos)
        stagnating = state.stagnation >= p.chaos_patience
        ck2 = jax.random.split(keys[9], 2)
        do_chaos = stagnating & (jax.random.uniform(ck2[0], (m, 1), dtype) < p.chaos_rate)
        chaotic = jnp.clip(arch[0] + p.chaos_strength * (2.0 * z - 1.0) * (hi - lo), lo, hi)
        x = jnp.where(do_chaos, chaotic, x)

        extra = jnp.zeros((), jnp.int32)
        functions = 1 + _num_constraints(problem)
        hessian = (n + 1) * (n + 2) // 2
        fd = fdf = jnp.zeros((), jnp.int32)  # finite-difference costs (module docstring)
        # local refinement: SQP-style steps from the archive's best as the last ants
        if self.refine_ants > 0:
            d = ch.sqp_direction(problem, arch[0], p.refine_active, p.repair_margin)
            alpha = 0.25 ** jnp.arange(self.refine_ants, dtype=dtype)
            cand = jnp.clip(arch[0][None, :] + alpha[:, None] * d[None, :], lo, hi)
            x = x.at[m - self.refine_ants:].set(cand)
            extra = extra + n + 1
            fd, fdf = fd + hessian, fdf + functions * hessian

        # gradient repair of infeasible ants
        margin = p.repair_margin * jnp.mean(hi - lo)
        enabled = jax.random.uniform(ck2[1], (m,), dtype) < p.p_repair
        if self.repair_steps > 0 and _num_constraints(problem) > 0:
            x, steps = jax.vmap(lambda a, e: ch.gradient_repair(
                problem, a, self.repair_steps, margin, e))(x, enabled)
            taken = jnp.sum(steps).astype(jnp.int32)
            extra = extra + taken
            fd, fdf = fd + taken * (n + 1), fdf + taken * (functions - 1) * (n + 1)
        return x, state.replace(chaos=z, evaluations=state.evaluations + extra,
                                fd_evaluations=state.fd_evaluations + fd,
                                fd_function_evaluations=state.fd_function_evaluations + fdf)

    def _chaotic_restart(self, state: ContinuousState, problem: Any) -> ContinuousState:
        """After ``restart_patience`` iterations without progress, re-seed the whole archive.

        The ``k`` members are placed by the archive's logistic-map sequences over the whole box,
        unevaluated (f = violation = +inf), so the next ants replace them. The best-so-far stays
        in ``best_solution`` / ``best_f`` (elitism of the result); the archive forgets it so the
        colony can leave its basin (keeping it there let it pull the colony back into the same
        local optimum on g13).
        """
        p = state.params
        lo, hi = problem.lower, problem.upper
        z = logistic_step(state.archive_chaos)
        restart = state.stagnation >= p.restart_patience

        def reseed(s: ContinuousState) -> ContinuousState:
            inf = jnp.full_like(s.archive_f, jnp.inf)
            return s.replace(archive_x=lo + z * (hi - lo), archive_f=inf, archive_v=inf,
                             stagnation=jnp.zeros_like(s.stagnation))

        state = jax.lax.cond(restart, reseed, lambda s: s, state)
        return state.replace(archive_chaos=z)

    # ----------------------------------------------------------------- tell
    def _tell(
        self, state: ContinuousState, solutions: Array, fitness: Evaluation, problem: Any
    ) -> tuple[ContinuousState, dict[str, Array]]:
        p = state.params
        f = fitness.f.astype(state.archive_f.dtype)
        v = fitness.violation.astype(state.archive_v.dtype)
        if self.constraint_method == "epsilon":  # epsilon(0) from the first evaluated ants
            first = ch.initial_epsilon(v, p.eps_fraction).astype(state.epsilon0.dtype)
            state = state.replace(
                epsilon0=jnp.where(state.iteration == 0, first, state.epsilon0))
        eps = ch.epsilon_schedule(state.iteration + 1, state.epsilon0, p.eps_cutoff,
                                  p.eps_exponent).astype(state.epsilon.dtype)
        if self.constraint_method != "epsilon":
            eps = state.epsilon
        all_x = jnp.concatenate([state.archive_x, solutions.astype(state.archive_x.dtype)])
        all_f = jnp.concatenate([state.archive_f, f])
        all_v = jnp.concatenate([state.archive_v, v])
        keep = self._order(all_f, all_v, p, eps)[: self.archive_size]

        # best so far by Deb's rules (feasible first), whatever the archive order is
        i = ch.rank_order(f, v, "deb")[0]
        improved = ch.better(f[i], v[i], state.best_f, state.best_violation, "deb")
        # stagnation counts iterations without *significant* progress: rounding-level gains
        # (a colony re-converging onto the same optimum) must not postpone a restart
        gain = state.best_f - f[i]
        significant = gain > 1e-9 * (1.0 + jnp.abs(state.best_f))
        progress = improved & ((state.best_violation > 0) | significant)
        best_f = jnp.where(improved, f[i], state.best_f)
        best_v = jnp.where(improved, v[i], state.best_violation)
        evaluations = state.evaluations + solutions.shape[0]
        target_evals, target_iter = state.target_evaluations, state.target_iteration
        target_fd, target_fdf = state.target_fd_evaluations, state.target_fd_function_evaluations
        f_star = getattr(problem, "f_star", None)
        if f_star is not None:
            hit = (best_v <= 0) & (best_f - f_star <= TARGET_TOLERANCE) & (target_evals < 0)
            target_evals = jnp.where(hit, evaluations, target_evals)
            target_fd = jnp.where(hit, state.fd_evaluations + solutions.shape[0],
                                  state.target_fd_evaluations)
            target_fdf = jnp.where(hit, state.fd_function_evaluations + solutions.shape[0],
                                   state.target_fd_function_evaluations)
            target_iter = jnp.where(hit, state.iteration + 1, target_iter)
        lo, hi = problem.lower, problem.upper
        ax = all_x[keep]
        diversity = jnp.clip(jnp.mean(jnp.std(ax, axis=0) / (hi - lo)) * 12**0.5, 0.0, 1.0)
        state = state.replace(
            archive_x=ax,
            archive_f=all_f[keep],
            archive_v=all_v[keep],
            epsilon=eps,
            best_f=best_f,
            best_violation=best_v,
            best_solution=jnp.where(improved, solutions[i].astype(ax.dtype), state.best_solution),
            best_cost=jnp.where(best_v > 0, jnp.inf, best_f).astype(jnp.float32),
            stagnation=jnp.where(progress, 0, state.stagnation + 1),
            target_evaluations=target_evals,
            target_iteration=target_iter,
            target_fd_evaluations=target_fd,
            target_fd_function_evaluations=target_fdf,
            fd_evaluations=state.fd_evaluations + solutions.shape[0],
            fd_function_evaluations=state.fd_function_evaluations + solutions.shape[0],
        )
        metrics = {
            "diversity": diversity.astype(jnp.float32),
            "best_f": best_f,
            "best_violation": best_v,
            "evaluations": evaluations,
            "epsilon": eps,
        }
        return state, metrics

    def scalar_cost(self, fitness: Evaluation) -> Array:
        """Objective of feasible ants, +inf for infeasible ones (iteration statistics)."""
        return jnp.where(fitness.violation > 0, jnp.inf, fitness.f).astype(jnp.float32)

    # ----------------------------------------------------------------- islands (migration)
    def best_fitness(self, state: ContinuousState) -> Evaluation:
        return Evaluation(f=state.best_f, violation=state.best_violation)

    def immigrate(
        self, state: ContinuousState, solutions: Array, fitness: Evaluation, key: Array,
        replace: str = "worst",
    ) -> ContinuousState:
        """Migrants replace the archive's worst (or random non-best) members, the archive is
        re-ranked, and the best-so-far adopts the best migrant by Deb's rules. A migrant that
        is already in the archive leaves its slot unchanged (no duplicates)."""
        p = state.params
        x = solutions.astype(state.archive_x.dtype)
        f = fitness.f.astype(state.archive_f.dtype)
        v = fitness.violation.astype(state.archive_v.dtype)
        slots = replacement_slots(key, self.archive_size, x.shape[0], replace)
        fresh = ~jnp.any(jnp.all(x[:, None, :] == state.archive_x[None, :, :], axis=-1), axis=-1)
        ax = state.archive_x.at[slots].set(jnp.where(fresh[:, None], x, state.archive_x[slots]))
        af = state.archive_f.at[slots].set(jnp.where(fresh, f, state.archive_f[slots]))
        av = state.archive_v.at[slots].set(jnp.where(fresh, v, state.archive_v[slots]))
        order = self._order(af, av, p, state.epsilon)
        i = ch.rank_order(f, v, "deb")[0]
        improved = ch.better(f[i], v[i], state.best_f, state.best_violation, "deb")
        significant = state.best_f - f[i] > 1e-9 * (1.0 + jnp.abs(state.best_f))
        progress = improved & ((state.best_violation > 0) | significant)
        best_f = jnp.where(improved, f[i], state.best_f)
        best_v = jnp.where(improved, v[i], state.best_violation)
        return state.replace(
            archive_x=ax[order], archive_f=af[order], archive_v=av[order],
            best_f=best_f, best_violation=best_v,
            best_solution=jnp.where(improved, x[i], state.best_solution),
            best_cost=jnp.where(best_v > 0, jnp.inf, best_f).astype(jnp.float32),
            stagnation=jnp.where(progress, 0, state.stagnation),
        )


def _num_constraints(problem: Any) -> int:
    return int(getattr(problem, "num_inequality", 0)) + int(getattr(problem, "num_equality", 0))
