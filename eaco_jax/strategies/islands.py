"""Island model: C colonies of any strategy at once, exchanging their best ants.

:class:`Islands` wraps a strategy; its state holds C inner states stacked on a leading island
axis (each island its own PRNG key stream and, optionally, its own hyper-parameters). ``ask``
vmaps the inner ask and returns the C colonies as one colony of ``C * m`` ants, so the problem
evaluates them in one batched call; ``tell`` splits the fitness back, vmaps the inner tell and,
every ``every`` iterations, migrates::

    result = ea.minimize(problem, Islands(GraphEACO(), islands=8, every=10))

Migration (a pure function of the state, :func:`migrate`):

* **emigrants**: each island offers its ``migrants`` best solutions among its best-so-far and
  the ants of this iteration (ranked by the strategy's scalar cost, then violation, then
  position; an ant identical to the best-so-far is not offered twice);
* **topology**: ``"ring"``: island j receives island j-1's emigrants; ``"all"``: the best
  ``migrants`` of every other island's emigrants; ``"random"``: those of one other island drawn
  uniformly at every migration;
* **replace**: the receiving island's :meth:`~eaco_jax.strategies.base.Strategy.immigrate`
  takes them: ContinuousEACO puts them into its archive in place of the worst (or random
  non-best) members; GraphEACO into its best-so-far / restart-best records (what the global
  update deposits on); strategies without a hook adopt the best migrant as their best-so-far.

``every=None`` never migrates: the islands are then C independent runs, bit for bit the same as
running each island's key alone (tested). The wrapper's own best-so-far is the best island's
(by violation, then objective), ``metrics["island_best_cost"]`` the per-island best.

Sharding (``shard=True``): the island axis of the state is split over a mesh of
``num_devices`` devices (default all, on every host after ``jax.distributed.initialize``) in
gcd(C, devices) groups, and the colony's ants over every device, with sharding constraints; XLA
runs each device's islands there, and migration (a roll or gather over the island axis) becomes
a collective. With C a multiple of the device count each device holds C / devices islands. What
the host reads (best-so-far, metrics) is replicated. See docs/islands.md (also for why results
agree with the unsharded run bit for bit for some strategies and to float rounding for others).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.errors import ConfigError
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import BASE_METRICS, State, Strategy

Array = jax.Array
PyTree = Any

TOPOLOGIES = ("ring", "all", "random")
REPLACEMENTS = ("worst", "random")


@struct.dataclass
class IslandsState(State):
    """The wrapper's state: the base fields describe the best island (global best).

    Attributes:
      islands: the C inner states, stacked on a leading island axis.
      best_f / best_violation: the global best's objective (full precision) and violation
        (0 for unconstrained strategies), so stop rules and results read them as for
        ContinuousEACO.
      best_island: the island that holds the global best.
      migrations: migrations done so far.
      migration_key: the key of the last ``ask``, drawn from for random topology / replacement.
    """

    islands: State
    best_f: Array
    best_violation: Array
    best_island: Array
    migrations: Array
    migration_key: Array


@dataclasses.dataclass(frozen=True)
class Islands(Strategy):
    """``islands`` colonies of ``strategy`` with migration (see the module docstring).

    Attributes:
      strategy: the inner colony (any strategy of the library except ``Islands``).
      islands: number of colonies C.
      every: migrate after every ``every``-th iteration; ``None``: never.
      migrants: emigrants per island per migration (k).
      topology: ``"ring"``, ``"all"`` or ``"random"``.
      replace: ``"worst"`` or ``"random"`` members of a receiving population.
      shard: split the island axis (and the colony) over a device mesh.
      num_devices: devices of that mesh (default: all).
      num_ants: C x the inner colony (derived; the driver budgets evaluations by it).
    """

    num_ants: int = dataclasses.field(init=False, default=0)
    strategy: Strategy = None  # type: ignore[assignment]  (required; checked below)
    islands: int = 4
    every: int | None = 10
    migrants: int = 1
    topology: str = "ring"
    replace: str = "worst"
    shard: bool = False
    num_devices: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.strategy, Strategy) or isinstance(self.strategy, Islands):
            raise ConfigError("Islands needs an inner strategy (GraphEACO(), ContinuousEACO(), "
                              f"...), got {self.strategy!r}")
        if self.islands < 1 or self.migrants < 1:
            raise ConfigError(f"islands and migrants must be >= 1, got {self.islands} and "
                              f"{self.migrants}")
        if self.every is not None and self.every < 1:
            raise ConfigError(f"every must be >= 1 or None (never), got {self.every}")
        if self.every is not None and not getattr(self.strategy, "migrates", True):
            raise ConfigError(f"{type(self.strategy).__name__} has no island migration: pass "
                              "every=None (independent islands) or run seeds side by side")
        if self.topology not in TOPOLOGIES:
            raise ConfigError(f"topology={self.topology!r} is not one of {TOPOLOGIES}")
        if self.replace not in REPLACEMENTS:
            raise ConfigError(f"replace={self.replace!r} is not one of {REPLACEMENTS}")
        if self.migrants > self.strategy.num_ants + 1:
            raise ConfigError(f"migrants={self.migrants} exceeds what an island can offer "
                              f"(its {self.strategy.num_ants} ants and its best-so-far)")
        object.__setattr__(self, "num_ants", self.islands * self.strategy.num_ants)

    @property
    def problem_kind(self) -> str:
        """The inner strategy's problem kind."""
        return self.strategy.problem_kind

    # ----------------------------------------------------------------- delegation
    def default_params(self, problem: Any = None) -> PyTree:
        """The inner strategy's defaults, shared by every island (sweeps override its fields)."""
        return self.strategy.default_params(problem)

    def prepare(self, problem: Any) -> Any:
        return self.strategy.prepare(problem)

    def max_charge(self, problem: Any = None) -> int:
        """Every island charges its own colony each iteration."""
        return self.islands * self.strategy.max_charge(problem)

    def charge_note(self, problem: Any = None) -> str:
        return f"{self.islands} islands x {self.strategy.charge_note(problem)}"

    def check_params(self, params: Any, where: str = "") -> None:
        """The inner strategy's ranges (per-island params are checked entry by entry)."""
        self.strategy.check_params(params, where)

    def inactive_params(self, params: Any) -> dict[str, str]:
        """The inner strategy's inactive fields; per-island params are judged on island 0."""
        first = jax.tree.map(lambda a: np.asarray(a)[0] if np.ndim(a) else a, params) \
            if any(np.ndim(a) for a in jax.tree.leaves(params)) else params
        return self.strategy.inactive_params(first)

    def scalar_cost(self, fitness: PyTree) -> Array:
        # whole on every device: the colony statistics then sum in the unsharded order
        return self._whole(self.strategy.scalar_cost(fitness))

    def best_fitness(self, state: IslandsState) -> PyTree:
        per_island = jax.vmap(self.strategy.best_fitness)(state.islands)
        return jax.tree.map(lambda a: a[state.best_island], per_island)

    def immigrate(self, state: State, solutions: Array, fitness: PyTree, key: Array,
                  replace: str = "worst") -> State:
        raise ConfigError("Islands cannot be nested inside Islands")

    # ----------------------------------------------------------------- helpers
    def island_keys(self, key: Array) -> Array:
        """The C islands' initial keys for the run key ``key`` (island i starts as a lone
        colony initialised with ``island_keys(key)[i]`` would)."""
        return jax.random.split(jax.random.fold_in(key, 1), self.islands)

    def per_island(self, params: Sequence[PyTree]) -> PyTree:
        """One Params per island (heterogeneous islands), stacked for :meth:`init`."""
        if len(params) != self.islands:
            raise ConfigError(f"per_island needs {self.islands} Params, got {len(params)}")
        return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *params)

    def _island_params(self, params: PyTree, problem: Any) -> PyTree:
        """``params`` with a leading island axis: shared leaves are broadcast, leaves that
        already have one (from :meth:`per_island`) are kept."""
        template = self.strategy.default_params(problem)
        if jax.tree.structure(template) != jax.tree.structure(params):
            raise ConfigError(f"params must be the inner strategy's "
                              f"{type(template).__name__}, got {type(params).__name__}")

        def leaf(t: Any, x: Any) -> Array:
            x = jnp.asarray(x)
            shape = np.shape(t)
            if x.shape == shape:
                return jnp.broadcast_to(x, (self.islands, *shape))
            if x.shape == (self.islands, *shape):
                return x
            raise ConfigError(f"a params leaf has shape {x.shape}; expected {shape} (shared) "
                              f"or {(self.islands, *shape)} (per island)")

        return jax.tree.map(leaf, template, params)

    def _mesh(self) -> Any:
        from eaco_jax.problems.sharding import island_mesh

        return island_mesh(self.islands, self.num_devices)

    def _split(self, tree: PyTree, every_device: bool = False) -> PyTree:
        """Islands split over the mesh's island groups (or, for the colony's ants,
        ``every_device``)."""
        if not self.shard:
            return tree
        from eaco_jax.problems.sharding import AXIS, ISLANDS, split_leading

        return split_leading(tree, self._mesh(), (ISLANDS, AXIS) if every_device else ISLANDS)

    def _whole(self, tree: PyTree) -> PyTree:
        if not self.shard:
            return tree
        from eaco_jax.problems.sharding import replicated

        return replicated(tree, self._mesh())

    def _place(self, state: IslandsState) -> IslandsState:
        """Sharded: islands split over the mesh, the wrapper's own fields whole everywhere."""
        if not self.shard:
            return state
        own = {f.name: getattr(state, f.name) for f in dataclasses.fields(state)
               if f.name != "islands"}
        return state.replace(islands=self._split(state.islands), **self._whole(own))

    def _with_global_best(self, state: IslandsState) -> IslandsState:
        """Base fields and best_f / best_violation from the best island."""
        f, v = island_objectives(state.islands)
        i = jnp.lexsort((f, v))[0]
        improved = (v[i] < state.best_violation) | (
            (v[i] == state.best_violation) & (f[i] < state.best_f))
        pick = dict(
            best_solution=state.islands.best_solution[i],
            best_cost=state.islands.best_cost[i],
            best_f=f[i].astype(state.best_f.dtype),
            best_violation=v[i].astype(state.best_violation.dtype),
            best_island=i.astype(jnp.int32))
        return state.replace(**pick, stagnation=jnp.where(improved, 0, state.stagnation + 1))

    # ----------------------------------------------------------------- init / ask / tell
    def _init(self, key: Array, problem: Any, params: PyTree) -> IslandsState:
        per_island = self._island_params(params, problem)
        inner = jax.vmap(lambda k, p: self.strategy.init(k, problem, p))(
            self.island_keys(key), per_island)
        f, v = island_objectives(inner)
        state = IslandsState(
            key=jax.random.fold_in(key, 0),
            params=per_island,
            iteration=jnp.zeros((), jnp.int32),
            evaluations=jnp.sum(inner.evaluations).astype(jnp.int32),
            best_solution=inner.best_solution[0],
            best_cost=jnp.asarray(jnp.inf, jnp.float32),
            stagnation=jnp.zeros((), jnp.int32),
            islands=inner,
            best_f=jnp.full((), jnp.inf, f.dtype),
            best_violation=jnp.full((), jnp.inf, v.dtype),
            best_island=jnp.zeros((), jnp.int32),
            migrations=jnp.zeros((), jnp.int32),
            migration_key=jax.random.fold_in(key, 2),
        )
        state = self._with_global_best(state)
        return self._place(state.replace(stagnation=jnp.zeros((), jnp.int32)))

    def _ask(self, key: Array, state: IslandsState, problem: Any) -> tuple[Array, IslandsState]:
        def one(s: State) -> tuple[Array, State]:  # as the driver steps a lone colony
            k, ask_key = jax.random.split(s.key)
            return self.strategy.ask(ask_key, s.replace(key=k), problem)

        xs, inner = jax.vmap(one)(state.islands)
        charged = jnp.sum(inner.evaluations - state.islands.evaluations)  # inside ask
        charged = charged.astype(state.evaluations.dtype)  # (x64 would widen the sum)
        solutions = self._split(xs.reshape((-1, *xs.shape[2:])), every_device=True)
        state = state.replace(islands=inner, migration_key=key,
                              evaluations=state.evaluations + charged)
        return solutions, self._place(state)

    def _tell(
        self, state: IslandsState, solutions: Array, fitness: PyTree, problem: Any
    ) -> tuple[IslandsState, dict[str, Array]]:
        c = self.islands
        xs = self._split(solutions.reshape((c, -1, *solutions.shape[1:])))
        fs = jax.tree.map(lambda f: f.reshape((c, -1, *f.shape[1:])), fitness)
        inner, inner_metrics = jax.vmap(
            lambda s, x, f: self.strategy.tell(s, x, f, problem))(state.islands, xs, fs)
        migrations = state.migrations
        if self.every is not None and c > 1:
            due = (state.iteration + 1) % self.every == 0
            inner = jax.lax.cond(
                due, lambda i: migrate(self, i, xs, fs, state.migration_key), lambda i: i,
                inner)
            migrations = migrations + due.astype(jnp.int32)
        state = self._place(self._with_global_best(
            state.replace(islands=inner, migrations=migrations)))
        metrics = {"island_best_cost": inner.best_cost, "best_island": state.best_island,
                   "migrations": migrations}
        own = {"best_f": state.best_f, "best_violation": state.best_violation,
               "evaluations": state.evaluations + solutions.shape[0]}
        # island means / totals over whole arrays: the unsharded summation order, exactly
        for name, value in self._whole(inner_metrics).items():
            if name in BASE_METRICS or name in metrics:
                continue
            if name in own:
                metrics[name] = own[name]
            elif jnp.issubdtype(value.dtype, jnp.floating):
                metrics[name] = jnp.mean(value, axis=0).astype(value.dtype)  # island mean
            else:
                metrics[name] = jnp.sum(value, axis=0).astype(value.dtype)  # island total
        return state, self._whole(metrics)


# --------------------------------------------------------------------------- migration
def island_objectives(islands: State) -> tuple[Array, Array]:
    """Per-island best objective and violation ``(C,)``: ``best_f`` / ``best_violation`` if
    the inner state has them (constrained colonies), else ``best_cost`` and 0."""
    f = getattr(islands, "best_f", None)
    if f is None:
        return islands.best_cost, jnp.zeros_like(islands.best_cost)
    return f, jnp.maximum(islands.best_violation, 0)


def _violation(fitness: PyTree) -> Array:
    if isinstance(fitness, Evaluation):
        return jnp.maximum(fitness.violation, 0).astype(jnp.float32)
    return jnp.zeros(jnp.shape(jax.tree.leaves(fitness)[0]), jnp.float32)


def _take(tree: PyTree, idx: Array) -> PyTree:
    """``a[c, idx[c, j]]`` for every leaf ``a`` with leading axes ``(C, n)``."""
    def one(a: Array) -> Array:
        i = idx.reshape(idx.shape + (1,) * (a.ndim - 2))
        return jnp.take_along_axis(a, i, axis=1)

    return jax.tree.map(one, tree)


def emigrants(
    strategy: Strategy, islands: State, xs: Array, fs: PyTree, k: int
) -> tuple[Array, PyTree]:
    """Each island's ``k`` best among its best-so-far and this iteration's ants ``xs``
    ``(C, m, ...)`` with fitness ``fs``: ``(C, k, ...)`` solutions and their fitness."""
    c, m = xs.shape[:2]
    best_x = islands.best_solution.astype(xs.dtype)
    best_f = jax.vmap(strategy.best_fitness)(islands)
    if isinstance(fs, Evaluation) and not isinstance(best_f, Evaluation):  # default hook
        best_f = Evaluation(f=best_f, violation=jnp.zeros_like(best_f))
    cand_x = jnp.concatenate([best_x[:, None], xs], axis=1)  # (C, m + 1, ...)
    cand_f = jax.tree.map(
        lambda b, f: jnp.concatenate([b[:, None].astype(f.dtype), f], axis=1), best_f, fs)
    cost = jax.vmap(strategy.scalar_cost)(cand_f).astype(jnp.float32)
    copy = jnp.all((xs == best_x[:, None]).reshape(c, m, -1), axis=-1)
    cost = cost.at[:, 1:].set(jnp.where(copy, jnp.inf, cost[:, 1:]))
    viol = jax.vmap(_violation)(cand_f)
    viol = viol.at[:, 1:].set(jnp.where(copy, jnp.inf, viol[:, 1:]))
    idx = jnp.lexsort((viol, cost), axis=-1)[:, :k]  # stable: position breaks ties
    return _take(cand_x, idx), _take(cand_f, idx)


def route(
    topology: str, ex: Array, ef: PyTree, cost: Array, viol: Array, key: Array
) -> tuple[Array, PyTree]:
    """Immigrants ``(C, k, ...)`` of each island from the emigrants ``ex`` / ``ef`` (with
    their scalar ``cost`` and ``viol`` ``(C, k)``) under ``topology``."""
    c, k = cost.shape
    if topology == "ring":  # island j <- island j - 1 (a collective permute when sharded)
        return jnp.roll(ex, 1, axis=0), jax.tree.map(lambda a: jnp.roll(a, 1, axis=0), ef)
    if topology == "random":  # island j <- one other island, uniformly
        src = (jnp.arange(c) + jax.random.randint(key, (c,), 1, c)) % c
        return ex[src], jax.tree.map(lambda a: a[src], ef)
    if topology == "all":  # island j <- the k best emigrants of all other islands
        owner = jnp.repeat(jnp.arange(c), k)
        mine = owner[None, :] == jnp.arange(c)[:, None]  # (C, C k)
        pool_cost = jnp.where(mine, jnp.inf, cost.reshape(-1)[None, :])
        pool_viol = jnp.where(mine, jnp.inf, viol.reshape(-1)[None, :])
        pick = jnp.lexsort((pool_viol, pool_cost), axis=-1)[:, :k]  # (C, k) into the pool

        def flat(a: Array) -> Array:
            return a.reshape((c * k, *a.shape[2:]))[pick]

        return flat(ex), jax.tree.map(flat, ef)
    raise ConfigError(f"topology={topology!r} is not one of {TOPOLOGIES}")


def migrate(wrapper: Islands, islands: State, xs: Array, fs: PyTree, key: Array) -> State:
    """One migration: emigrants -> topology -> each island's ``immigrate`` (pure)."""
    inner = wrapper.strategy
    k_route, k_replace = jax.random.split(key)
    ex, ef = emigrants(inner, islands, xs, fs, wrapper.migrants)
    cost = jax.vmap(inner.scalar_cost)(ef).astype(jnp.float32)
    ix, ifit = route(wrapper.topology, ex, ef, cost, jax.vmap(_violation)(ef), k_route)
    keys = jax.random.split(k_replace, wrapper.islands)
    return jax.vmap(lambda s, x, f, kk: inner.immigrate(s, x, f, kk, wrapper.replace))(
        islands, ix, ifit, keys)
