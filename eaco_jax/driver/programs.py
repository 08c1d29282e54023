"""The compiled chunk: one ask -> evaluate -> tell iteration, ``lax.scan`` over a chunk of them
(vmapped over rows), and this process's lookup of compiled programs (chunks and initialisers),
through the on-disk program cache (:mod:`eaco_jax.driver.program_cache`)."""

from __future__ import annotations

import collections
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.driver import program_cache
from eaco_jax.driver.interrupt import polled
from eaco_jax.strategies.base import State, Strategy


def _nan_count(fitness: Any) -> jax.Array:
    """Ants whose evaluation holds a NaN (objective or violation; several objectives per ant
    count once)."""
    leaves = [jnp.isnan(f).reshape(f.shape[:1] + (-1,)).any(axis=1) if jnp.ndim(f) > 1
              else jnp.isnan(f) for f in jax.tree.leaves(fitness)
              if jnp.issubdtype(jnp.asarray(f).dtype, jnp.floating)]
    if not leaves:
        return jnp.zeros((), jnp.int32)
    return jnp.any(jnp.stack(leaves), axis=0).sum().astype(jnp.int32)


def iteration_step(strategy: Strategy, problem: Any, state: State) -> tuple[State, dict]:
    """One ask -> evaluate -> tell round; the keys for it are split off ``state.key``.

    A problem with ``stochastic = True`` (a gait under fresh randomised worlds) gets its own
    key too: ``problem.evaluate(solutions, key=...)``.
    """
    if getattr(problem, "stochastic", False):
        key, ask_key, eval_key = jax.random.split(state.key, 3)
        solutions, state = strategy.ask(ask_key, state.replace(key=key), problem)
        fitness = problem.evaluate(solutions, key=eval_key)
    else:
        key, ask_key = jax.random.split(state.key)
        solutions, state = strategy.ask(ask_key, state.replace(key=key), problem)
        fitness = problem.evaluate(solutions)
    state, metrics = strategy.tell(state, solutions, fitness, problem)
    return state, {**metrics, NAN_KEY: _nan_count(fitness)}


#: history column counting NaN evaluations per iteration (all-NaN runs are refused)
NAN_KEY = "nan_evaluations"
#: history column (dropped before the result) marking the iterations a capped row ran
RAN_KEY = "_ran"


def _skipped(metrics: Any, state: State) -> dict:
    """History entries of an iteration that did not run: NaN (floats), -1 (ints), and the
    unchanged best cost."""

    def fill(name: str, a: Any) -> jax.Array:
        if name == "best_cost":
            return jnp.asarray(state.best_cost, a.dtype).reshape(a.shape)
        if jnp.issubdtype(a.dtype, jnp.floating):
            return jnp.full(a.shape, jnp.nan, a.dtype)
        return jnp.full(a.shape, -1 if jnp.issubdtype(a.dtype, jnp.integer) else 0, a.dtype)

    return {k: fill(k, a) for k, a in metrics.items()}


def make_chunk_fn(strategy: Strategy, length: int, batched: bool,
                  capped: bool = False) -> Callable:
    """A jitted ``(problem, state, active[, budget]) -> (state, history)`` over ``length``
    iterations.

    Only the first ``active`` (a traced int) iterations run; the rest pass the state through
    (``lax.cond``), so a run's last, shorter chunk reuses the same compiled program. The
    caller drops the history rows past ``active``. ``capped``: an iteration also runs only
    if the evaluations charged so far plus the most one iteration can charge
    (``strategy.max_charge``) stay within ``budget`` (a traced int), and the history gets a
    ``_ran`` column.
    """

    def run(problem, state, active, budget=None):
        per_iteration = strategy.max_charge(problem) if capped else 0

        def step(s, i):
            def skip(s):
                shapes = jax.eval_shape(lambda t: iteration_step(strategy, problem, t)[1], s)
                if capped:
                    return s, _skipped(shapes, s)
                return s, jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype), shapes)

            go = i < active
            if capped:
                go = go & (s.evaluations.astype(jnp.int32) + per_iteration <= budget)
            s, hist = jax.lax.cond(go, lambda s: iteration_step(strategy, problem, s), skip, s)
            if capped:
                hist = {**hist, RAN_KEY: go}
            return s, hist

        return jax.lax.scan(step, state, jnp.arange(length))

    if batched:
        axes = (None, 0, None, None) if capped else (None, 0, None)
        run = jax.vmap(run, in_axes=axes)
    return jax.jit(run)


_COMPILED: collections.OrderedDict[Any, Any] = collections.OrderedDict()
_COMPILED_MAX = 32
_INITS: collections.OrderedDict[Any, Any] = collections.OrderedDict()
#: the share of Linux's vm.max_map_count past which kept programs are let go: each XLA:CPU
#: program holds memory maps of its own (claim program-maps-per-program), so the 32 chunks and
#: 32 initialisers the LRU keeps can fill most of the default limit, and a process at the
#: limit dies inside XLA (a segfault) at its next compilation (claim program-maps-peak)
_MAPS_SHARE = 0.5


def memory_maps() -> tuple[int, int] | None:
    """(memory maps this process holds, vm.max_map_count), or None where Linux's /proc does
    not say."""
    try:
        with open("/proc/sys/vm/max_map_count") as fh:
            limit = int(fh.read())
        with open("/proc/self/maps", "rb") as fh:
            used = sum(chunk.count(b"\n") for chunk in iter(lambda: fh.read(1 << 20), b""))
    except (OSError, ValueError):
        return None
    return used, limit


def _make_room() -> None:
    """Forget the oldest compiled programs (chunks and initialisers alike, oldest first of
    each) while the process holds more than :data:`_MAPS_SHARE` of its allowed memory maps."""
    import gc

    while _COMPILED or _INITS:
        m = memory_maps()
        if m is None or m[0] <= _MAPS_SHARE * m[1]:
            return
        for cache in (_COMPILED, _INITS):
            for _ in range((len(cache) + 1) // 2):  # the older half of each
                cache.popitem(last=False)
        gc.collect()


def device_view(problem: Any) -> Any:
    """``problem`` as compiled programs take it: without host-only metadata (a problem's
    ``device_view()``, e.g. a TSP's name, optimum and coordinates as read), which would
    otherwise enter the programs' keys, so that a new instance of the same shapes and
    settings reuses a compiled program instead of tracing it again."""
    view = getattr(problem, "device_view", None)
    return problem if view is None else view()


def signature(tree: Any) -> tuple:
    """Shapes, dtypes and shardings of ``tree``'s leaves: what a compiled chunk is bound to."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    return treedef, tuple((tuple(np.shape(x)), str(getattr(x, "dtype", type(x))),
                           bool(getattr(x, "weak_type", False)),
                           getattr(x, "sharding", None) if isinstance(x, jax.Array) else None)
                          for x in leaves)


def budget_arg(budget: int | None) -> jax.Array:
    return jnp.asarray(budget if budget is not None else 2**31 - 1, jnp.int32)


def compiled_chunk(strategy: Strategy, length: int, batched: bool, problem: Any,
                   state: State, capped: bool = False,
                   interrupted: Callable[[], bool] | None = None) -> tuple[Any, float]:
    """The compiled chunk for these shapes, static configuration and JAX options (those that
    shape a trace), and the seconds spent compiling it now (0.0 from this process's cache).

    With ``interrupted`` (a poll), compilation runs in a worker thread and
    :class:`CompileInterrupted` is raised as soon as the poll says so.
    """
    key = ("chunk", strategy, length, batched, capped, program_cache.trace_flags(),
           signature(problem), signature(state))
    args = (problem, state, jnp.int32(length)) + ((budget_arg(None),) if capped else ())
    return _program(_COMPILED, key, lambda: make_chunk_fn(strategy, length, batched, capped),
                    args, strategy, interrupted)


def _program(cache: collections.OrderedDict, key: tuple, make: Callable[[], Callable],
             args: tuple, strategy: Strategy,
             interrupted: Callable[[], bool] | None = None) -> tuple[Any, float]:
    """This process's compiled program for ``key`` (an LRU of :data:`_COMPILED_MAX` in
    ``cache``), else ``make()`` compiled for ``args`` now, through the on-disk program cache
    where the program may be kept there; and the seconds spent now (0.0 from ``cache``)."""
    if key in cache:
        cache.move_to_end(key)
        return cache[key], 0.0
    t0 = time.perf_counter()
    disk_key = (program_cache.program_key(key) if program_cache.single_device(args)
                and program_cache.package_code_only(strategy, *args) else None)
    _make_room()
    compiled, _how = polled(lambda: program_cache.compiled(make(), args, disk_key),
                             interrupted)
    cache[key] = compiled
    while len(cache) > _COMPILED_MAX:
        cache.popitem(last=False)
    return compiled, time.perf_counter() - t0


def clear_compiled() -> None:
    """Forget this process's compiled chunks and initialisers (the next run compiles again,
    or loads from the on-disk caches)."""
    _COMPILED.clear()
    _INITS.clear()


def compiled_init(strategy: Strategy, rows: str, problem: Any, keys: jax.Array,
                  params: Any) -> tuple[Callable, float]:
    """The compiled ``(keys, problem, params) -> state`` (through the on-disk program cache)
    and the seconds spent on it now (0.0 when this process had it):
    ``rows`` "one" (one seed, an unbatched state), "shared" (a row per key, one params) or
    "per_row" (a row per key and params row)."""
    key = ("init", strategy, rows, program_cache.trace_flags(), signature(problem),
           signature(keys), signature(params))

    def init(keys, problem, params):
        if rows == "one":
            return strategy._init_jit(keys[0], problem, params)
        axes = 0 if rows == "per_row" else None
        return jax.vmap(lambda k, p: strategy._init_jit(k, problem, p), (0, axes))(keys, params)

    return _program(_INITS, key, lambda: jax.jit(init), (keys, problem, params), strategy)
