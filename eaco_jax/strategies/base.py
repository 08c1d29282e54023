"""The strategy contract every colony in eaco_jax follows (evosax / optax style).

A strategy is a frozen, hashable object holding *static* configuration only (number of ants,
which operators exist at all, array shapes). Everything that may change between runs of the
same compiled program - hyper-parameters, pheromone, archive, PRNG key - lives in a
:class:`State` pytree. The problem is passed in, never stored, so a batch of states (seeds or
hyper-parameter settings, vmapped) shares one copy of the problem's data::

    state = strategy.init(key, problem, params)            # evaluates nothing
    solutions, state = strategy.ask(key, state, problem)
    fitness = problem.evaluate(solutions)                   # or your own evaluator
    state, metrics = strategy.tell(state, solutions, fitness, problem)

``fitness`` is what ``problem.evaluate`` returns: ``(m,)`` costs for graph and path problems,
an :class:`~eaco_jax.problems.base.Evaluation` (objective and violation) for continuous ones.
It may come from anywhere (numpy, a simulator, a lab): ``init`` evaluates nothing, so a loop
of ask -> your evaluator -> tell drives every strategy. ``metrics`` is a dict of scalars that
the driver records as the run's history; telemetry lives there, not in the state.

Hyper-parameters are a ``Params`` pytree (a ``flax.struct`` dataclass with its defaults on
the class; switches are booleans) stored in ``state.params``, so a batch of states built
from a batch of params is a vmappable sweep.

Subclasses implement ``_init``, ``_ask`` and ``_tell``; the base keeps the best-so-far
bookkeeping helpers, the iteration / evaluation counters and the colony statistics in one
place, maps NaN costs to +inf once, and jits the public methods with ``self`` static.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.errors import ConfigError

Array = jax.Array
PyTree = Any

#: metrics every strategy reports each iteration (the driver's history columns)
BASE_METRICS = ("best_cost", "iter_best_cost", "iter_mean_cost")


@struct.dataclass
class State:
    """Fields every colony state carries. Strategies subclass this with their own fields.

    Attributes:
      key: the run's PRNG key stream; the driver splits one key per iteration from it.
      params: the strategy's hyper-parameters (a traced pytree, vmappable).
      iteration: completed ask/tell rounds.
      evaluations: solutions charged so far (the colony, plus what a strategy charges itself).
      best_solution: best solution found so far (minimisation).
      best_cost: its scalar cost (for constrained problems: its objective value if feasible).
      stagnation: iterations since best_cost last improved.
    """

    key: Array
    params: Any  # the strategy's Params pytree
    iteration: Array
    evaluations: Array
    best_solution: Array
    best_cost: Array
    stagnation: Array


def base_fields(key: Array, params: PyTree, solution_template: Array) -> dict[str, Any]:
    """Initial values of the :class:`State` fields, for a subclass's ``_init``."""
    return dict(
        key=key,
        params=params,
        iteration=jnp.zeros((), jnp.int32),
        evaluations=jnp.zeros((), jnp.int32),
        best_solution=solution_template,
        best_cost=jnp.array(jnp.inf, jnp.float32),
        stagnation=jnp.zeros((), jnp.int32),
    )


def as_params(params: PyTree, dtype: Any = jnp.float32) -> PyTree:
    """``params`` with every leaf an array: booleans stay bool, numbers become ``dtype``.

    Params dataclasses hold Python defaults; this is where they become traced leaves.
    """

    def leaf(x: Any) -> Array:
        a = jnp.asarray(x)
        return a if a.dtype == jnp.bool_ else jnp.asarray(x, dtype)

    return jax.tree.map(leaf, params)


# --------------------------------------------------------------------------- parameter ranges
@dataclasses.dataclass(frozen=True)
class Range:
    """The documented range of one hyper-parameter (checked on the host before a run).

    ``low``/``high`` are bounds (``None``: unbounded); ``open_low``/``open_high`` exclude
    them; ``boolean`` fields take only True/False (1/0).
    """

    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False
    boolean: bool = False

    def __str__(self) -> str:
        if self.boolean:
            return "True/False"
        if self.low is not None and self.high is not None:
            return (f"{'(' if self.open_low else '['}{self.low:g}, {self.high:g}"
                    f"{')' if self.open_high else ']'}")
        if self.low is not None:
            return f"{'>' if self.open_low else '>='} {self.low:g}"
        if self.high is not None:
            return f"{'<' if self.open_high else '<='} {self.high:g}"
        return "any finite number"

    def bad(self, values: np.ndarray) -> np.ndarray:
        """Mask of the entries of ``values`` outside the range."""
        v = np.asarray(values)
        if self.boolean:
            return ~np.isin(v.astype(np.float64), (0.0, 1.0))
        v = v.astype(np.float64)
        out = ~np.isfinite(v)
        if self.low is not None:
            out |= (v <= self.low) if self.open_low else (v < self.low)
        if self.high is not None:
            out |= (v >= self.high) if self.open_high else (v > self.high)
        return out


#: shorthands for Params range declarations
UNIT = Range(0.0, 1.0)  # a probability or fraction
BOOL = Range(boolean=True)
NONNEG = Range(0.0)
POSITIVE = Range(0.0, open_low=True)
AT_LEAST_ONE = Range(1.0)


def _is_concrete(x: Any) -> bool:
    return not isinstance(x, jax.core.Tracer)


def check_ranges(params: Any, ranges: dict[str, Range], where: str = "") -> None:
    """One :class:`ConfigError` line for the first concrete field outside its range.

    Traced values (inside ``jit``/``vmap``) are skipped: only concrete values are checked.
    Stacked params (a leading batch axis) are checked entry by entry.
    """
    if not dataclasses.is_dataclass(params):
        return
    cls = type(params).__name__
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        r = ranges.get(f.name)
        if r is None or not _is_concrete(value):
            continue
        try:
            arr = np.asarray(value)
            bad = r.bad(arr)
        except (TypeError, ValueError):
            raise ConfigError(f"{where}{cls}.{f.name}={value!r} is not a number "
                              f"(range {r})") from None
        if np.any(bad):
            shown = arr.reshape(-1)[int(np.flatnonzero(bad.reshape(-1))[0])]
            shown = shown.item() if hasattr(shown, "item") else shown
            if isinstance(shown, float) and not math.isfinite(shown):
                shown = repr(shown)
            raise ConfigError(f"{where}{cls}.{f.name}={shown} is outside its range {r}")


def ranges_table(params_cls: type) -> str:
    """A Markdown table of a Params class's fields, defaults and ranges (for the docs)."""
    ranges = getattr(params_cls, "RANGES", {})
    rows = [f"| `{params_cls.__name__}` field | default | range |", "|---|---|---|"]
    for f in dataclasses.fields(params_cls):
        rows.append(f"| `{f.name}` | `{f.default!r}` | {ranges.get(f.name, '')} |")
    return "\n".join(rows)


def _jit_method(fn):
    """jit a strategy method with ``self`` static (strategies are frozen dataclasses)."""
    return functools.wraps(fn)(jax.jit(fn, static_argnums=0))


@dataclasses.dataclass(frozen=True)
class Strategy:
    """Base class. Subclasses are ``@dataclasses.dataclass(frozen=True)`` with static fields.

    Subclass hooks:
      default_params(problem) -> Params pytree (arrays; see :func:`as_params`)
      _init(key, problem, params) -> State
      _ask(key, state, problem) -> (solutions, state)
      _tell(state, solutions, fitness, problem) -> (state, metrics)
        (update the best-so-far, e.g. with :func:`record_best`; the base adds the counters
        and :data:`BASE_METRICS`)
      scalar_cost(fitness) -> (m,) float32 used for the colony statistics.
    """

    num_ants: int = 40

    @property
    def problem_kind(self) -> str:
        """The problem kind this strategy solves (``"graph"``, ``"path"``, ``"continuous"``,
        ``"multiobjective"``; ``""``: any). A strategy declares it as a class constant,
        ``problem_kind: ClassVar[str] = "graph"`` (not a field: it is no setting); a wrapper
        whose kind is its inner strategy's (:class:`~eaco_jax.strategies.islands.Islands`)
        overrides this read-only property."""
        return ""

    # ----------------------------------------------------------------- subclass hooks
    def default_params(self, problem: Any = None) -> PyTree:
        raise NotImplementedError(f"{type(self).__name__} must define default_params")

    def _init(self, key: Array, problem: Any, params: PyTree) -> State:
        raise NotImplementedError(f"{type(self).__name__} must define _init")

    def _ask(self, key: Array, state: State, problem: Any) -> tuple[Array, State]:
        raise NotImplementedError(f"{type(self).__name__} must define _ask")

    def _tell(
        self, state: State, solutions: Array, fitness: PyTree, problem: Any
    ) -> tuple[State, dict[str, Array]]:
        raise NotImplementedError(f"{type(self).__name__} must define _tell")

    def scalar_cost(self, fitness: PyTree) -> Array:
        """Per-ant scalar cost used for statistics (default: fitness itself)."""
        return fitness

    def prepare(self, problem: Any) -> Any:
        """The problem as this strategy needs it (checked, converted); called by ``init``."""
        return problem

    def max_charge(self, problem: Any = None) -> int:
        """The most evaluations one iteration can charge (``max_evaluations`` never starts an
        iteration that could exceed the budget). Default: one colony."""
        return int(self.num_ants)

    def charge_note(self, problem: Any = None) -> str:
        """How :meth:`max_charge` is made up, for messages."""
        return f"{self.num_ants} ants"

    def check_params(self, params: Any, where: str = "") -> None:
        """Check concrete hyper-parameters against their documented ranges (``RANGES`` on the
        Params class); one :class:`ConfigError` line naming field, value and range."""
        check_ranges(params, getattr(type(params), "RANGES", {}), where)

    def inactive_params(self, params: Any) -> dict[str, str]:
        """Params fields that have no effect under these switches (concrete ``params``):
        name -> the switch that would make it act. Default: none."""
        return {}

    # ----------------------------------------------------------------- migration hooks
    # (used by strategies.islands.Islands; plain functions of the state, not jitted here)
    def best_fitness(self, state: State) -> PyTree:
        """Fitness of ``state.best_solution`` in the form ``tell`` receives (default: the
        scalar ``best_cost``), so an island's best-so-far can migrate with its fitness."""
        return state.best_cost

    def immigrate(
        self, state: State, solutions: Array, fitness: PyTree, key: Array,
        replace: str = "worst",
    ) -> State:
        """Take ``k`` migrants ``solutions`` (``(k, ...)``, already evaluated) from another
        island. ``replace`` ("worst" or "random") says which members of a population they
        displace (see :func:`replacement_slots`); ``key`` draws the random ones.

        Default: the best migrant becomes the best-so-far if it is better
        (:func:`adopt_best`); strategies with a population or trails override this.
        """
        return adopt_best(state, solutions, self.scalar_cost(fitness))

    # ----------------------------------------------------------------- public, jitted
    def init(self, key: Array, problem: Any, params: PyTree | None = None) -> State:
        """Fresh colony state for ``problem`` (nothing is evaluated).

        ``params=None`` takes ``default_params(problem)``.
        """
        problem = self.prepare(problem)
        if params is None:
            params = self.default_params(problem)
        self.check_params(params)
        return self._init_jit(key, problem, params)

    @_jit_method
    def _init_jit(self, key: Array, problem: Any, params: PyTree) -> State:
        return self._init(key, problem, params)

    @_jit_method
    def ask(self, key: Array, state: State, problem: Any) -> tuple[Array, State]:
        """Construct one colony of candidate solutions (shape ``(num_ants, ...)``)."""
        return self._ask(key, state, problem)

    def tell(
        self, state: State, solutions: Array, fitness: PyTree, problem: Any
    ) -> tuple[State, dict[str, Array]]:
        """Update the colony with the evaluated ``solutions``; NaN costs count as +inf.

        ``fitness`` is what the problem's ``evaluate`` returns: an ``(m,)`` array of costs for
        graph and path strategies, an ``Evaluation(f, violation)`` for continuous ones.
        Returns the new state and this iteration's metrics (scalars).
        """
        self.check_fitness(fitness)
        return self._tell_jit(state, solutions, fitness, problem)

    def check_fitness(self, fitness: PyTree) -> None:
        """One ConfigError line, before anything is traced, for a continuous strategy told
        plain costs: it ranks by objective and violation, so it needs an ``Evaluation``."""
        from eaco_jax.problems.base import Evaluation

        if self.problem_kind == "continuous" and not isinstance(fitness, Evaluation):
            raise ConfigError(
                f"{type(self).__name__}.tell needs fitness as ea.Evaluation(f, violation) (what "
                f"a continuous problem's evaluate returns), got {type(fitness).__name__}; wrap "
                "your costs f: ea.Evaluation(f=f, violation=jnp.zeros_like(f))")

    @_jit_method
    def _tell_jit(
        self, state: State, solutions: Array, fitness: PyTree, problem: Any
    ) -> tuple[State, dict[str, Array]]:
        fitness = jax.tree.map(lambda f: jnp.where(jnp.isnan(f), jnp.inf, f), fitness)
        state, metrics = self._tell(state, solutions, fitness, problem)
        cost = self.scalar_cost(fitness)
        finite = jnp.isfinite(cost)
        n_finite = jnp.maximum(finite.sum(), 1)
        state = state.replace(
            iteration=state.iteration + 1,
            evaluations=state.evaluations + solutions.shape[0],
        )
        base = {
            "best_cost": state.best_cost,
            "iter_best_cost": jnp.min(cost).astype(jnp.float32),
            "iter_mean_cost": (jnp.where(finite, cost, 0.0).sum() / n_finite).astype(
                jnp.float32),
        }
        return state, {**base, **metrics}


def record_best(state: State, solutions: Array, cost: Array) -> State:
    """Update best-so-far with the lowest-cost ant of ``solutions`` (plain minimisation)."""
    i = jnp.argmin(cost)
    improved = cost[i] < state.best_cost
    return state.replace(
        best_solution=jnp.where(improved, solutions[i], state.best_solution),
        best_cost=jnp.where(improved, cost[i], state.best_cost).astype(jnp.float32),
        stagnation=jnp.where(improved, 0, state.stagnation + 1),
    )


def adopt_best(state: State, solutions: Array, cost: Array) -> State:
    """Best-so-far from ``solutions`` not produced by this colony (migrants): like
    :func:`record_best`, but stagnation only changes (to 0) when the record improves."""
    i = jnp.argmin(cost)
    improved = cost[i] < state.best_cost
    return state.replace(
        best_solution=jnp.where(improved, solutions[i], state.best_solution),
        best_cost=jnp.where(improved, cost[i], state.best_cost).astype(jnp.float32),
        stagnation=jnp.where(improved, 0, state.stagnation),
    )


def replacement_slots(key: Array, size: int, k: int, replace: str) -> Array:
    """Which ``k`` members of a best-first population of ``size`` migrants replace.

    ``"worst"``: the last ``k`` ranks. ``"random"``: ``k`` distinct random ranks, never rank 0
    (the population's best survives, as elitism requires).
    """
    if replace == "worst":
        if k > size:
            raise ConfigError(f"{k} migrants cannot replace members of a population of {size}")
        return jnp.arange(size - k, size)
    if replace == "random":
        if k > size - 1:
            raise ConfigError(f"{k} migrants cannot replace random non-best members of a "
                              f"population of {size}")
        return 1 + jax.random.permutation(key, size - 1)[:k]
    raise ConfigError(f"replace={replace!r} is not one of ('worst', 'random')")
