"""Multi-objective EACO: the continuous colony's archive sampling, ranked by Pareto fronts.

The pheromone is again a ranked archive of ``k`` solutions (ACO_R, Socha & Dorigo 2008), but
ranked as NSGA-II ranks a population (Deb et al. 2002): by non-dominated front under
*constrained domination* (feasible before infeasible, less violation before more, then Pareto
dominance; :mod:`eaco_jax.ops.pareto`), and within a front by crowding distance, so the
isolated members of the front (its extremes first) lead. Each iteration:

* **Construction** (``ask``): every ant picks a guide by ACO_R's rank weight
  ``exp(-l^2 / (2 (locality k)^2))`` over that order and redraws each coordinate with
  probability ``p_coordinate`` (at least one) from a Gaussian around the guide, of width
  ``rho * mean |x_e - x_guide|`` over the archive; with probability ``p_crossover`` it is
  instead the Laplace-crossover child of the guide and a second rank-weighted member, and
  with probability ``p_mutation`` it is then power-mutated in ``1/n`` of its coordinates
  (:mod:`eaco_jax.ops.real_ops`). Bounds are exact (clipped).
* **Archive update** (``tell``): the best ``k`` of archive + colony by (front, -crowding):
  elitist, so the first front never loses a member unless it has more than ``k`` of them.

Metrics: ``hypervolume`` of the archive's feasible first front w.r.t. the problem's fixed
``ref_point`` (exact, :func:`eaco_jax.ops.pareto.hypervolume`; NaN for more than three
objectives), ``front_size`` and ``feasible``. ``best_cost`` is minus the largest hypervolume
seen (everything is minimised; ``problem.shown_best`` shows it positive) and ``stagnation``
counts iterations without a larger one. ``best_solution`` is the archive's first member. The
front itself is :meth:`MOEACO.front`.

Evaluation accounting: one evaluation per ant; the initial archive is drawn uniformly and not
evaluated (its objectives are +inf), so the first colony replaces it.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.ops import pareto
from eaco_jax.ops.real_ops import laplace_crossover_sample, power_mutation_sample
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import (
    POSITIVE,
    UNIT,
    Range,
    State,
    Strategy,
    as_params,
    base_fields,
)

Array = jax.Array


@struct.dataclass
class MOParams:
    """Traced hyper-parameters of the multi-objective colony (vmappable).

    Defaults chosen by measurement (claims ``mo-zdt1-colony-hv``, ``mo-dtlz2-colony-hv``):
    redrawing few coordinates per ant with a wide Gaussian moves along the front without
    undoing what the other coordinates have reached.
    """

    rho: Array = 1.5  # ACO_R xi: Gaussian width = rho * archive spread around the guide
    locality: Array = 0.2  # ACO_R q: rank-weight locality (small -> guides from the top ranks)
    p_coordinate: Array = 0.1  # probability each coordinate is redrawn (at least one is)
    p_crossover: Array = 0.1  # probability an ant is a Laplace-crossover child
    p_mutation: Array = 0.2  # probability an ant is power-mutated
    laplace_a: Array = 0.0  # Laplace crossover location a
    laplace_b: Array = 0.15  # Laplace crossover scale b
    power_index: Array = 10.0  # power mutation index p

    #: documented ranges, checked on the host before a run (concrete values only)
    RANGES: ClassVar[dict[str, Range]] = {
        "rho": POSITIVE, "locality": POSITIVE, "p_coordinate": UNIT, "p_crossover": UNIT,
        "p_mutation": UNIT, "laplace_a": Range(), "laplace_b": POSITIVE,
        "power_index": POSITIVE,
    }


@struct.dataclass
class MOState(State):
    archive_x: Array  # (k, n) best first by (front, -crowding); unevaluated entries: f = inf
    archive_f: Array  # (k, objectives)
    archive_v: Array  # (k,) total violation
    archive_rank: Array  # (k,) front index (0 = non-dominated)
    hypervolume: Array  # of the archive's feasible first front


@dataclasses.dataclass(frozen=True)
class MOEACO(Strategy):
    """Multi-objective continuous ant colony (see the module docstring)."""

    num_ants: int = 100
    archive_size: int = 100
    problem_kind: ClassVar[str] = "multiobjective"

    def __post_init__(self) -> None:
        if self.num_ants < 1 or self.archive_size < 2:
            raise ConfigError("MOEACO needs num_ants >= 1 and archive_size >= 2")

    def default_params(self, problem: Any = None) -> MOParams:
        return MOParams()

    def inactive_params(self, params: MOParams) -> dict[str, str]:
        """Fields without effect under these switches -> the switch that makes them act."""
        def off(name: str) -> bool:
            return bool(jnp.all(jnp.asarray(getattr(params, name)) <= 0))

        dead: dict[str, str] = {}
        if off("p_crossover"):
            dead.update(dict.fromkeys(("laplace_a", "laplace_b"), "p_crossover > 0"))
        if off("p_mutation"):
            dead["power_index"] = "p_mutation > 0"
        return dead

    def prepare(self, problem: Any) -> Any:
        """Check that ``problem`` has several objectives, box bounds and a reference point."""
        if getattr(problem, "kind", None) != "multiobjective" or not hasattr(problem, "ref_point"):
            raise ProblemError(
                "MOEACO needs a multi-objective problem with box bounds and a ref_point "
                "(eaco_jax.problems.MultiObjectiveProblem, problems.get('zdt1')), got "
                f"{type(problem).__name__}")
        return problem

    def check_fitness(self, fitness: Any) -> None:
        """One ConfigError line, before tracing, unless ``fitness`` is an Evaluation whose
        ``f`` has one row of objectives per ant."""
        if not isinstance(fitness, Evaluation) or np.ndim(fitness.f) != 2:
            raise ConfigError(
                "MOEACO.tell needs fitness as ea.Evaluation(f, violation) with f of shape "
                "(ants, objectives) (what a multi-objective problem's evaluate returns), got "
                f"{type(fitness).__name__}")

    # ----------------------------------------------------------------- init
    def _init(self, key: Array, problem: Any, params: MOParams) -> MOState:
        """Archive drawn uniformly in the box, not evaluated (f = violation = +inf)."""
        dtype = problem.dtype
        params = as_params(params, dtype)
        k_arch, k_run = jax.random.split(key)
        lo, hi = problem.lower, problem.upper
        x = lo + (hi - lo) * jax.random.uniform(k_arch, (self.archive_size, problem.dim), dtype)
        k = self.archive_size
        return MOState(
            **base_fields(k_run, params, x[0]),
            archive_x=x,
            archive_f=jnp.full((k, problem.num_objectives), jnp.inf, dtype),
            archive_v=jnp.full((k,), jnp.inf, dtype),
            archive_rank=jnp.zeros((k,), jnp.int32),
            hypervolume=jnp.zeros((), dtype),
        )

    # ----------------------------------------------------------------- ask
    def _ask(self, key: Array, state: MOState, problem: Any) -> tuple[Array, MOState]:
        p = state.params
        lo, hi = problem.lower, problem.upper
        m, k, n = self.num_ants, self.archive_size, problem.dim
        dtype = problem.dtype
        arch = state.archive_x
        keys = jax.random.split(key, 10)

        ranks = jnp.arange(k, dtype=dtype)
        logw = -(ranks**2) / (2.0 * (p.locality * k) ** 2)
        guide = jax.random.categorical(keys[0], logw, shape=(m,))
        partner = jax.random.categorical(keys[1], logw, shape=(m,))
        xg = arch[guide]

        # Gaussian redraw of some coordinates around the guide (width from the archive spread)
        spread = jnp.mean(jnp.abs(arch[None, :, :] - xg[:, None, :]), axis=1) * k / (k - 1)
        sigma = jnp.maximum(p.rho * spread, 1e-12 * (hi - lo))
        drawn = jnp.clip(xg + sigma * jax.random.normal(keys[2], (m, n), dtype), lo, hi)
        redraw = (jax.random.uniform(keys[3], (m, n), dtype) < p.p_coordinate) | (
            jnp.arange(n)[None, :] == jax.random.randint(keys[4], (m, 1), 0, n))
        x = jnp.where(redraw, drawn, xg)

        # Laplace crossover of guide and partner (one of the two offspring, at random)
        y1, y2 = jax.vmap(lambda kk, a, b: laplace_crossover_sample(
            kk, a, b, lo, hi, p.laplace_a, p.laplace_b))(
                jax.random.split(keys[5], m), xg, arch[partner])
        child = jnp.where(jax.random.bernoulli(keys[6], 0.5, (m, 1)), y1, y2)
        x = jnp.where(jax.random.uniform(keys[7], (m, 1), dtype) < p.p_crossover, child, x)

        # power mutation: mutated ants change each coordinate w.p. 1/n (at least one)
        mk = jax.random.split(keys[8], 3)
        mutated = jax.vmap(lambda kk, a: power_mutation_sample(kk, a, lo, hi, p.power_index))(
            jax.random.split(mk[0], m), x)
        coord = (jax.random.uniform(mk[1], (m, n), dtype) < 1.0 / n) | (
            jnp.arange(n)[None, :] == jax.random.randint(mk[2], (m, 1), 0, n))
        do_mut = jax.random.uniform(keys[9], (m, 1), dtype) < p.p_mutation
        return jnp.where(do_mut & coord, mutated, x), state

    # ----------------------------------------------------------------- tell
    def _tell(
        self, state: MOState, solutions: Array, fitness: Evaluation, problem: Any
    ) -> tuple[MOState, dict[str, Array]]:
        f = fitness.f.astype(state.archive_f.dtype)
        v = fitness.violation.astype(state.archive_v.dtype)
        all_x = jnp.concatenate([state.archive_x, solutions.astype(state.archive_x.dtype)])
        all_f = jnp.concatenate([state.archive_f, f])
        all_v = jnp.concatenate([state.archive_v, v])
        order, rank, _ = pareto.rank_crowding_order(all_f, all_v)
        keep = order[: self.archive_size]
        ax, af, av, ar = all_x[keep], all_f[keep], all_v[keep], rank[keep]
        first = (ar == 0) & (av <= 0) & jnp.all(jnp.isfinite(af), axis=-1)
        if problem.num_objectives <= 3:
            hv = pareto.hypervolume(af, problem.ref_point.astype(af.dtype), first)
        else:
            hv = jnp.asarray(jnp.nan, af.dtype)
        improved = -hv < state.best_cost
        state = state.replace(
            archive_x=ax, archive_f=af, archive_v=av, archive_rank=ar, hypervolume=hv,
            best_solution=ax[0],
            best_cost=jnp.where(improved, -hv, state.best_cost).astype(jnp.float32),
            stagnation=jnp.where(improved, 0, state.stagnation + 1),
        )
        metrics = {
            "hypervolume": hv.astype(jnp.float32),
            "front_size": jnp.sum(first).astype(jnp.int32),
            "feasible": jnp.mean(v <= 0).astype(jnp.float32),
        }
        return state, metrics

    def scalar_cost(self, fitness: Evaluation) -> Array:
        """Sum of the objectives of feasible ants, +inf for infeasible ones (the iteration
        statistics' ``iter_best_cost``/``iter_mean_cost``; the archive ranks by fronts)."""
        total = jnp.sum(fitness.f, axis=-1)
        return jnp.where(fitness.violation > 0, jnp.inf, total).astype(jnp.float32)

    # ----------------------------------------------------------------- reading the front
    @staticmethod
    def front(state: MOState) -> dict[str, np.ndarray]:
        """The archive's feasible first front of one state (host arrays): ``x`` (points),
        ``f`` (their objectives) and ``violation``, sorted by the first objective."""
        rank, v = np.asarray(state.archive_rank), np.asarray(state.archive_v)
        f, x = np.asarray(state.archive_f), np.asarray(state.archive_x)
        if rank.ndim != 1:
            raise ConfigError("MOEACO.front takes one state; for a batch (seeds) pass "
                              "jax.tree.map(lambda a: a[i], state)")
        sel = (rank == 0) & (v <= 0) & np.all(np.isfinite(f), axis=-1)
        order = np.argsort(f[sel][:, 0], kind="stable")
        return {"x": x[sel][order], "f": f[sel][order], "violation": v[sel][order]}
