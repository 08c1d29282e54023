"""The run driver: many ask/evaluate/tell iterations inside ``lax.scan``, in compiled chunks.

One chunk of iterations is one compiled call; between chunks the host updates the progress
bar, asks the stop rules (:mod:`eaco_jax.driver.stop`) and writes checkpoints
(:class:`Checkpointing`). Several seeds, or several hyper-parameter settings times seeds, run
as one vmapped call. Compiled chunks are cached: a second ``minimize`` with the same strategy,
shapes and chunk length compiles nothing.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import math
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.driver import program_cache
from eaco_jax.driver.history import merge_history
from eaco_jax.driver.stop import Callback, Patience, Progress, StopRule, Target, WallTime
from eaco_jax.errors import ConfigError, Interrupted, ProblemError
from eaco_jax.strategies.base import State, Strategy


@dataclasses.dataclass(frozen=True)
class Checkpointing:
    """Where and how often :func:`minimize` saves the run (see :mod:`eaco_jax.driver.checkpoint`).

    A folder that already holds a checkpoint of this same run is resumed from its newest
    complete step (bit-identical to an unbroken run); one of another run is refused.

    Attributes:
      directory: the checkpoint folder.
      every / seconds: save after the chunk in which this many iterations / seconds have passed
        since the last save (the end of the run is always saved). ``every`` also caps the
        default chunk length so saves land on it.
      keep: how many checkpoints to keep.
      run_info: JSON-able dict stored with each checkpoint (``eaco resume`` reads
        ``{"command": run kind, "args": settings}`` from it).
    """

    directory: str | Path
    every: int | None = None
    seconds: float | None = None
    keep: int = 3
    run_info: dict[str, Any] | None = None


@dataclasses.dataclass
class Result:
    """What :func:`minimize` returns. With several rows (seeds, settings) every array has a
    leading row axis.

    ``history`` maps a metric name to an array over iterations (best so far, iteration best,
    iteration mean, diversity, plus strategy-specific metrics; with ``max_evaluations`` a row
    that stopped before the others has NaN there). ``stop_reason`` says why the run ended:
    ``"iterations"`` (the iteration budget), ``"max_evaluations"`` (the next iteration could
    have charged more than the budget left), ``"interrupted"`` or the name of the stop rule
    that fired. ``evaluations`` is what each row was charged (the colony plus what a strategy
    charges itself, e.g. gradient repair), never more than ``max_evaluations``.
    ``compile_seconds`` is what this call spent compiling or loading programs (the initial
    state's and the chunks'; 0 when the process had them), ``seconds`` that plus compute.

    The returned solution is re-checked on the host: ``best_cost`` is a TSP tour's exact
    length, and for constrained problems ``f``, ``violation`` and ``feasible`` come from a
    float64 evaluation of ``x`` (``feasible``: every inequality ``g(x) <= tolerance["inequality"]``
    and every ``|h(x)| <= tolerance["equality"]``).
    """

    best_solution: np.ndarray
    best_cost: np.ndarray
    history: dict[str, np.ndarray]
    iterations: int
    evaluations: np.ndarray
    seconds: float
    compile_seconds: float
    seconds_per_iteration: float
    state: State
    problem: Any
    strategy: Strategy
    seeds: list[int]
    stop_reason: str = "iterations"
    max_evaluations: int | None = None
    f: np.ndarray | None = None
    violation: np.ndarray | None = None
    feasible: np.ndarray | None = None
    tolerance: dict[str, float] | None = None
    precision: str = "float32"

    def __post_init__(self) -> None:
        if self.f is None:
            self.f = np.asarray(getattr(self.state, "best_f", self.best_cost))
        if self.violation is None:
            v = getattr(self.state, "best_violation", None)
            self.violation = np.zeros_like(self.best_cost) if v is None else np.asarray(v)
        if self.feasible is None:
            self.feasible = np.asarray(self.violation) <= 0

    @property
    def batched(self) -> bool:
        return len(self.seeds) > 1 or np.ndim(self.best_cost) > 0

    @property
    def x(self) -> np.ndarray:
        """The best solution (alias of ``best_solution``)."""
        return self.best_solution


def default_strategy(problem: Any) -> Strategy:
    """The EACO strategy for the problem's kind."""
    kind = getattr(problem, "kind", None)
    if kind == "graph":
        from eaco_jax.strategies.graph_eaco import GraphEACO

        return GraphEACO()
    if kind == "path":
        from eaco_jax.strategies.path_eaco import PathEACO

        return PathEACO()
    if kind == "continuous":
        from eaco_jax.strategies.continuous_eaco import ContinuousEACO

        if not getattr(problem, "differentiable", True):  # simulations: no gradient steps
            return ContinuousEACO(refine_ants=0, repair_steps=0)
        return ContinuousEACO()
    if kind == "multiobjective":
        from eaco_jax.strategies.mo_eaco import MOEACO

        return MOEACO()
    raise ProblemError(
        "minimize() needs a problem with kind 'graph', 'path', 'continuous' or "
        "'multiobjective', got "
        f"{type(problem).__name__} with kind={kind!r}; "
        "build one with eaco_jax.problems (TSP, ConstrainedProblem, ...)."
    )


# --------------------------------------------------------------------------- one iteration
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
_RAN = "_ran"


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
                hist = {**hist, _RAN: go}
            return s, hist

        return jax.lax.scan(step, state, jnp.arange(length))

    if batched:
        axes = (None, 0, None, None) if capped else (None, 0, None)
        run = jax.vmap(run, in_axes=axes)
    return jax.jit(run)


_COMPILED: collections.OrderedDict[Any, Any] = collections.OrderedDict()
_COMPILED_MAX = 32


def _signature(tree: Any) -> tuple:
    """Shapes, dtypes and shardings of ``tree``'s leaves: what a compiled chunk is bound to."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    return treedef, tuple((tuple(np.shape(x)), str(getattr(x, "dtype", type(x))),
                           bool(getattr(x, "weak_type", False)),
                           getattr(x, "sharding", None) if isinstance(x, jax.Array) else None)
                          for x in leaves)


def _budget_arg(budget: int | None) -> jax.Array:
    return jnp.asarray(budget if budget is not None else 2**31 - 1, jnp.int32)


def compiled_chunk(strategy: Strategy, length: int, batched: bool, problem: Any,
                   state: State, capped: bool = False,
                   interrupted: Callable[[], bool] | None = None) -> tuple[Any, float]:
    """The compiled chunk for these shapes, static configuration and JAX options (those that
    shape a trace), and the seconds spent compiling it now (0.0 from this process's cache).

    With ``interrupted`` (a poll), compilation runs in a worker thread and
    :class:`_Interrupt` is raised as soon as the poll says so.
    """
    key = ("chunk", strategy, length, batched, capped, program_cache.trace_flags(),
           _signature(problem), _signature(state))
    args = (problem, state, jnp.int32(length)) + ((_budget_arg(None),) if capped else ())
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
    compiled, _how = _polled(lambda: program_cache.compiled(make(), args, disk_key),
                             interrupted)
    cache[key] = compiled
    while len(cache) > _COMPILED_MAX:
        cache.popitem(last=False)
    return compiled, time.perf_counter() - t0


class _Interrupt(Exception):
    """Raised inside the driver when SIGINT/SIGTERM arrived (turned into :class:`Interrupted`)."""


def _polled(fn: Callable[[], Any], interrupted: Callable[[], bool] | None) -> Any:
    """``fn()`` in a worker thread, polled every 0.1 s so a signal can stop the wait."""
    if interrupted is None:
        return fn()
    box: dict[str, Any] = {}
    x64 = bool(jax.config.jax_enable_x64)  # JAX's config scopes are per thread

    def target() -> None:
        try:
            with jax.enable_x64(x64):
                box["value"] = fn()
        except BaseException as err:  # noqa: BLE001 - re-raised in the caller's thread
            box["error"] = err

    worker = threading.Thread(target=target, name="eaco-compile", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(0.1)
        if interrupted():
            raise _Interrupt
    if "error" in box:
        raise box["error"]
    return box["value"]


class _Signals:
    """SIGINT / SIGTERM set a flag (the driver stops at the next chunk boundary) and say so at
    once, naming the iteration the current chunk ends at (``at``); a second signal exits at
    once. Installed only in the main thread."""

    def __init__(self, newline: bool = False) -> None:
        self.name: str | None = None
        self.at = 0
        self._newline = newline  # a progress bar holds the current line
        self._old: dict[int, Any] = {}
        self._err: int | None = None  # stderr as it was (a save may point fd 2 elsewhere)

    def __enter__(self) -> _Signals:
        if threading.current_thread() is not threading.main_thread():
            return self
        sys.stderr.flush()
        self._err = os.dup(2)
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self._old[sig] = signal.signal(sig, self._handle)
            except (ValueError, OSError):  # pragma: no cover - exotic embeddings
                pass
        return self

    def _handle(self, signum: int, frame: Any) -> None:
        if self.name is not None:  # second signal: stop now
            self._say("\ninterrupted again: exiting without saving\n")
            os._exit(130)
        self.name = signal.Signals(signum).name
        self._say(f"{chr(10) if self._newline else ''}{self.name}: stopping after the current "
                  f"chunk (iteration {self.at}); send again to stop now\n")

    def _say(self, text: str) -> None:
        sys.stderr.flush()
        os.write(self._err if self._err is not None else 2, text.encode())

    def __exit__(self, *exc: Any) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        if self._err is not None:
            os.close(self._err)
            self._err = None

    def __call__(self) -> bool:
        return self.name is not None


# --------------------------------------------------------------------------- setup helpers
def initial_state(
    strategy: Strategy, problem: Any, seeds: Sequence[int], params: Any | None = None
) -> State:
    """The initial state for one seed, or a vmapped batch of states.

    ``params`` is one Params pytree (default: ``strategy.default_params(problem)``) or a list
    of them (a batch of settings): then row ``r`` belongs to ``params[r // len(seeds)]`` with
    seed ``seeds[r % len(seeds)]``. Concrete params are checked against their ranges first.
    """
    return _initial_state(strategy, problem, seeds, params)[0]


def _initial_state(strategy: Strategy, problem: Any, seeds: Sequence[int],
                   params: Any | None = None) -> tuple[State, float]:
    """:func:`initial_state` and the seconds spent compiling (or loading) its program."""
    problem = strategy.prepare(problem)
    if isinstance(params, list | tuple):
        for i, p in enumerate(params):
            strategy.check_params(p, where=f"params[{i}]: " if len(params) > 1 else "")
        stacked = stack_params(list(params))
        flat = jax.tree.map(lambda x: jnp.repeat(x, len(seeds), axis=0), stacked)
        keys = jnp.stack([jax.random.key(int(s)) for s in list(seeds) * len(params)])
        init, seconds = _compiled_init(strategy, "per_row", problem, keys, flat)
        return init(keys, problem, flat), seconds
    keys = jnp.stack([jax.random.key(int(s)) for s in seeds])
    if params is None:
        params = strategy.default_params(problem)
    strategy.check_params(params)
    rows = "one" if len(seeds) == 1 else "shared"
    init, seconds = _compiled_init(strategy, rows, problem, keys, params)
    return init(keys, problem, params), seconds


_INITS: collections.OrderedDict[Any, Any] = collections.OrderedDict()


def clear_compiled() -> None:
    """Forget this process's compiled chunks and initialisers (the next run compiles again,
    or loads from the on-disk caches)."""
    _COMPILED.clear()
    _INITS.clear()


def _compiled_init(strategy: Strategy, rows: str, problem: Any, keys: jax.Array,
                   params: Any) -> tuple[Callable, float]:
    """The compiled ``(keys, problem, params) -> state`` (through the on-disk program cache)
    and the seconds spent on it now (0.0 when this process had it):
    ``rows`` "one" (one seed, an unbatched state), "shared" (a row per key, one params) or
    "per_row" (a row per key and params row)."""
    key = ("init", strategy, rows, program_cache.trace_flags(), _signature(problem),
           _signature(keys), _signature(params))

    def init(keys, problem, params):
        if rows == "one":
            return strategy._init_jit(keys[0], problem, params)
        axes = 0 if rows == "per_row" else None
        return jax.vmap(lambda k, p: strategy._init_jit(k, problem, p), (0, axes))(keys, params)

    return _program(_INITS, key, lambda: jax.jit(init), (keys, problem, params), strategy)


def stack_params(params: Sequence[Any]) -> Any:
    """Stack a list of same-structure Params pytrees along a new leading axis."""
    if not params:
        raise ConfigError("params sequence is empty")
    structures = {str(jax.tree_util.tree_structure(p)) for p in params}
    if len(structures) > 1:
        raise ConfigError("every params set must have the same fields (one Params type)")
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *params)


#: evaluation counters are int32
MAX_EVALUATIONS = 2**31 - 1 - 2**24


def _count(name: str, value: Any, low: int = 1, high: int = 2**31 - 1) -> int:
    """An integer setting in ``[low, high]`` (one ConfigError line otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        if not (isinstance(value, float) and value.is_integer()):
            raise ConfigError(f"{name} must be an integer, got {value!r}")
    if not low <= int(value) <= high:
        raise ConfigError(f"{name}={value} is outside its range {low}..{high}")
    return int(value)


def resolve_iterations(
    strategy: Strategy, iterations: int | None, max_evaluations: int | None,
    problem: Any = None,
) -> int:
    """The iteration budget from ``iterations`` or ``max_evaluations`` (default 100).

    With ``max_evaluations`` this is an upper bound (every iteration charges at least
    ``num_ants``); the driver stops each row before an iteration could exceed the budget.
    """
    if iterations is not None and max_evaluations is not None:
        raise ConfigError("give iterations or max_evaluations, not both")
    if max_evaluations is not None:
        budget = _count("max_evaluations", max_evaluations, 1, MAX_EVALUATIONS)
        per_iteration = strategy.max_charge(problem)
        if budget < per_iteration:
            raise ConfigError(
                f"max_evaluations={budget} is below what one iteration can charge "
                f"({per_iteration}: {strategy.charge_note(problem)}); raise it or use fewer ants")
        return max(1, budget // strategy.num_ants)
    iterations = 100 if iterations is None else iterations
    return _count("iterations", iterations, 1, 2**31 - 1)


def checked_seeds(strategy: Strategy, problem: Any, seed: int | Sequence[int]) -> list[int]:
    """The seeds as a list, after checking that ``strategy`` solves ``problem``'s kind."""
    kind = getattr(problem, "kind", None)
    if strategy.problem_kind and kind != strategy.problem_kind:
        raise ProblemError(
            f"{type(strategy).__name__} solves '{strategy.problem_kind}' problems, "
            f"but {getattr(problem, 'name', problem)!r} is '{kind}'"
        )
    raw = [seed] if np.ndim(seed) == 0 else list(seed)
    if not raw:
        raise ConfigError("seed sequence is empty")
    return [_count("seed", s, 0, 2**32 - 1) for s in raw]


def default_chunk(total: int, chunk_size: int | None, checkpoint_every: int | None = None) -> int:
    """Iterations per compiled call: given, else ~20 chunks per run.

    (Checkpoints cut chunks short where they are due, so ``checkpoint_every`` no longer
    changes the chunk length; the argument is kept for callers.)
    """
    if chunk_size is not None:
        return _count("chunk_size", chunk_size)
    return max(1, math.ceil(total / 20))


def stop_rules(
    target: float | None = None,
    patience: int | None = None,
    max_seconds: float | None = None,
    callback: Callable[[Any, Progress], Any] | None = None,
    stop: StopRule | Sequence[StopRule] | None = None,
) -> list[tuple[str, StopRule]]:
    """The named stop rules of :func:`minimize`'s keywords."""
    rules: list[tuple[str, StopRule]] = []
    if target is not None:
        if not math.isfinite(float(target)):
            raise ConfigError(f"target must be a finite number, got {target!r}")
        rules.append(("target", Target(float(target))))
    if patience is not None:
        rules.append(("patience", Patience(_count("patience", patience))))
    if max_seconds is not None:
        if not (isinstance(max_seconds, int | float) and max_seconds > 0
                and math.isfinite(max_seconds)):
            raise ConfigError(f"max_seconds must be a number > 0, got {max_seconds!r}")
        rules.append(("max_seconds", WallTime(float(max_seconds))))
    if callback is not None:
        rules.append(("callback", Callback(callback)))
    if stop is not None:
        for r in ([stop] if callable(stop) else list(stop)):
            rules.append((getattr(r, "__name__", type(r).__name__), r))
    return rules


PRECISIONS = ("auto", "float32", "float64")


def _float_leaves(tree: Any) -> list[Any]:
    return [x for x in jax.tree.leaves(tree)
            if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating)]


def needs_float64(problem: Any, precision: str = "auto") -> bool:
    """Whether :func:`minimize` runs ``problem`` in float64 (see the README's rule).

    ``auto``: float64 for a problem that holds float64 arrays (built inside
    :func:`eaco_jax.problems.float64`) or has constraints (inequality or equality) and is
    differentiable JAX code; otherwise the problem's own dtype. ``float32`` with a float64
    problem is refused (one line).
    """
    if precision not in PRECISIONS:
        raise ConfigError(f"precision={precision!r} is not one of {', '.join(PRECISIONS)}")
    has64 = any(x.dtype == np.float64 for x in _float_leaves(problem))
    if precision == "float64":
        return True
    if precision == "float32":
        if has64:
            raise ConfigError(
                f"problem {getattr(problem, 'name', '')!r} holds float64 arrays (built inside "
                "float64()); use precision='float64' or 'auto', or build it outside float64()")
        return False
    constrained = (int(getattr(problem, "num_inequality", 0))
                   + int(getattr(problem, "num_equality", 0))) > 0
    return has64 or (constrained and bool(getattr(problem, "differentiable", True)))


def as_float64(problem: Any) -> Any:
    """``problem`` with its floating-point arrays in float64 (call inside a float64 scope)."""
    return jax.tree.map(
        lambda x: jnp.asarray(x, jnp.float64)
        if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating) else x, problem)


def _memory_limit() -> int:
    """Bytes the default device may hold (GPU: its memory; CPU: physical memory)."""
    try:
        stats = jax.devices()[0].memory_stats() or {}
        if stats.get("bytes_limit"):
            return int(stats["bytes_limit"])
    except Exception:  # noqa: BLE001 - memory_stats is optional per backend
        pass
    from eaco_jax.problems.tsplib import memory_bytes

    return memory_bytes()


def memory_limit() -> int:
    """Bytes the default device may hold (what colony states are measured against)."""
    return _memory_limit()


def state_row_bytes(strategy: Strategy, problem: Any, params: Any) -> int:
    """Bytes of one row of the colony state (abstract: nothing allocated)."""
    shapes = jax.eval_shape(lambda k: strategy.init(k, problem, params), jax.random.key(0))
    return sum(int(np.prod(a.shape)) * a.dtype.itemsize for a in jax.tree.leaves(shapes)
               if hasattr(a, "dtype") and not jnp.issubdtype(a.dtype, jax.dtypes.prng_key))


#: bytes per ant and city of one graph-colony iteration besides the state (construction's tours,
#: visited masks and candidate rows, the next state's tours): XLA's memory analysis of one step
#: on pr1002 gives 27 on a CPU
GRAPH_ANT_CITY_BYTES = 32
#: local search, per searched tour and city: a base plus one term per scanned candidate (XLA's
#: memory analysis of the batched or-2opt on pr1002: 750 B at 8 candidates, 1,710 B at 20)
LS_CITY_BYTES, LS_CANDIDATE_BYTES = 112, 80
#: continuous refinement (SQP steps with autodiff Hessians): dim x dim matrices of the problem's
#: dtype per iteration (XLA's memory analysis at dim 1,000: 14 in float32, 12 in float64)
HESSIAN_MATRICES = 14
#: one iteration's working set from which minimize warns (one line) before it starts
WARN_WORKING_SET = 2**30


def working_set_bytes(strategy: Strategy, problem: Any) -> tuple[int, str]:
    """Estimated bytes one iteration of one row allocates besides its state, and what they are
    (for the messages): the per-ant arrays of tour construction and local search on graph
    problems, the dim x dim Hessians of continuous refinement; 0 for what is not modelled."""
    m = int(strategy.num_ants)
    if getattr(problem, "kind", None) == "graph" and hasattr(problem, "n"):
        n = int(problem.n)
        work, what = GRAPH_ANT_CITY_BYTES * m * n, f"building {m} tours of {n} cities"
        if getattr(strategy, "local_search", "none") != "none":
            searched = min(m, int(getattr(strategy, "ls_best_k", None) or m))
            width = int(getattr(problem, "neighbors", np.zeros((n, 0))).shape[-1])
            scanned = min(width, int(getattr(strategy, "ls_neighbors", None) or width))
            work += searched * n * (LS_CITY_BYTES + LS_CANDIDATE_BYTES * scanned)
            what += f" and searching {searched} of them"
        return work, what
    if getattr(problem, "kind", None) == "continuous" and getattr(strategy, "refine_ants", 0):
        dim = int(getattr(problem, "dim", 0))
        itemsize = np.dtype(getattr(problem, "dtype", np.float32)).itemsize
        return (HESSIAN_MATRICES * itemsize * dim * dim,
                f"refinement's {dim} x {dim} Hessians")
    return 0, ""


def check_state_memory(strategy: Strategy, problem: Any, rows: int, params: Any) -> None:
    """Refuse a colony whose state, or state plus one iteration's working set
    (:func:`working_set_bytes`), would not fit in memory (abstract: nothing allocated); warn in
    one line when one iteration needs more than :data:`WARN_WORKING_SET`."""
    one = params[0] if isinstance(params, list | tuple) else params
    need, limit = state_row_bytes(strategy, problem, one) * rows, _memory_limit()
    colony = f"{type(strategy).__name__}(num_ants={strategy.num_ants})"
    if need > limit // 2:
        raise ConfigError(
            f"the colony state needs {need / 2**30:.1f} GiB ({rows} row(s) of {colony}), more "
            f"than half of the {limit / 2**30:.1f} GiB available; use fewer ants, seeds or "
            "settings")
    work, what = working_set_bytes(strategy, problem)
    total = need + work * rows
    name = getattr(problem, "name", type(problem).__name__)
    if total > limit // 2:
        fix = "use fewer ants, seeds or settings"
        if getattr(problem, "kind", None) == "graph":  # both parts grow with the ants
            most = max(1, int(strategy.num_ants * (limit // 2) / total))
            fix = f"use fewer ants (at most ~{most}), seeds or settings"
        elif "Hessians" in what:
            fix = f"use {type(strategy).__name__}(refine_ants=0) (derivative-free, linear in dim)"
        raise ConfigError(
            f"{colony} on {name!r} needs ~{total / 2**30:.1f} GiB per iteration ({rows} row(s): "
            f"the state and {what}), more than half of the {limit / 2**30:.1f} GiB available; "
            f"{fix}")
    if work * rows >= WARN_WORKING_SET:
        hint = (f" ({type(strategy).__name__}(refine_ants=0) is derivative-free, linear in dim)"
                if "Hessians" in what else "")
        warnings.warn(
            f"{colony} on {name!r} needs ~{total / 2**30:.1f} GiB per iteration ({rows} "
            f"row(s): the state and {what}); expect slow iterations{hint}", stacklevel=3)


# --------------------------------------------------------------------------- the driver
def minimize(
    problem: Any,
    strategy: Strategy | None = None,
    *,
    seed: int | Sequence[int] = 0,
    params: Any | Sequence[Any] | None = None,
    iterations: int | None = None,
    max_evaluations: int | None = None,
    target: float | None = None,
    patience: int | None = None,
    max_seconds: float | None = None,
    callback: Callable[[Any, Progress], Any] | None = None,
    stop: StopRule | Sequence[StopRule] | None = None,
    chunk_size: int | None = None,
    progress: bool = False,
    checkpointing: Checkpointing | None = None,
    precision: str = "auto",
) -> Result:
    """Minimise ``problem`` with an EACO colony (or any strategy of the library).

    Args:
      problem: a graph, path or continuous problem (see :mod:`eaco_jax.problems`).
      strategy: the colony; default :func:`default_strategy` for the problem's kind.
      seed: an int in ``0..2**32-1``, or a sequence of them to run several seeds as one
        vmapped call.
      params: hyper-parameters (default ``strategy.default_params(problem)``), or a list of
        Params to run every setting x every seed as one vmapped call (row ``r`` is
        ``params[r // len(seeds)]`` with seed ``seeds[r % len(seeds)]``). Concrete values are
        checked against each field's documented range before anything runs.
      iterations / max_evaluations: the budget (one of them; default 100 iterations).
        ``max_evaluations`` is a hard cap on the evaluations charged to each row: an
        iteration that could charge more than what is left is not started.
      target / patience / max_seconds / callback / stop: stop rules, checked after every
        chunk (see :mod:`eaco_jax.driver.stop`): every row's best <= target; every row
        stagnated ``patience`` iterations; compute seconds (compilation excluded);
        ``callback(state, progress)`` returned True; any further ``rule(state, progress)``.
      chunk_size: iterations per compiled call (default: about 20 chunks per run).
      progress: show a progress bar (tqdm).
      checkpointing: save (and resume) the run, see :class:`Checkpointing`.
      precision: ``"auto"`` (float64 for problems with constraints or float64 arrays, see
        :func:`needs_float64`), ``"float32"`` or ``"float64"``; a float64 run is scoped to
        this call whatever scope it is called in.

    SIGINT / SIGTERM (Ctrl-C) stop the run at the next chunk boundary (or during
    compilation) and raise :class:`~eaco_jax.errors.Interrupted` with the result so far
    (``err.result``), after a final checkpoint when checkpointing.
    """
    strategy = default_strategy(problem) if strategy is None else strategy
    seeds = checked_seeds(strategy, problem, seed)
    use64 = needs_float64(problem, precision)
    scope = jax.enable_x64(True) if use64 else contextlib.nullcontext()
    with scope:
        if use64:
            problem = as_float64(problem)
        problem = strategy.prepare(problem)
        total = resolve_iterations(strategy, iterations, max_evaluations, problem)
        chunk = default_chunk(total, chunk_size)
        n_settings = len(params) if isinstance(params, list | tuple) else 1
        rows = len(seeds) * n_settings
        rules = stop_rules(target, patience, max_seconds, callback, stop)
        if params is None:
            params = strategy.default_params(problem)
        check_state_memory(strategy, problem, rows, params)
        state, init_seconds = _initial_state(strategy, problem, seeds, params)
        row_seeds = seeds * n_settings
        return run(strategy, problem, state, total=total, chunk=chunk, seeds=row_seeds,
                   rules=rules, progress=progress, checkpointing=checkpointing,
                   max_evaluations=max_evaluations, compile_seconds=init_seconds)


def shown_best(problem: Any, best_cost: Any) -> float:
    """The best of the rows' ``best_cost`` as the user reads it: the problem's
    ``shown_best(cost)`` if it has one (a maximised fitness shows its own sign), else the cost."""
    best = float(np.min(np.asarray(best_cost)))
    shown = getattr(problem, "shown_best", None)
    return float(shown(best)) if callable(shown) else best


def _exhausted(strategy: Strategy, problem: Any, state: State, budget: int | None) -> bool:
    """Whether no row can start another iteration within ``budget``."""
    if budget is None:
        return False
    charged = np.asarray(state.evaluations, np.int64)
    return bool(np.all(charged + strategy.max_charge(problem) > budget))


def _trim(hist: dict[str, Any], length: int, batched: bool) -> dict[str, np.ndarray]:
    """The chunk's history up to ``length`` (and, for capped runs, the last iteration any
    row ran), without the ``_ran`` column."""
    ran = hist.get(_RAN)
    if ran is not None:
        ran = np.asarray(ran)
        any_ran = ran.any(axis=0) if batched else ran
        idx = np.flatnonzero(any_ran[:length])
        length = int(idx[-1]) + 1 if idx.size else 0
    cut = (slice(None), slice(length)) if batched else (slice(length),)
    return {k: np.asarray(v)[cut] for k, v in hist.items() if k != _RAN}


class _NanTally:
    """Running count of evaluations and NaN evaluations per row (from the history's
    ``nan_evaluations`` column, -1 where an iteration did not run): a row whose every
    evaluation so far was NaN is a broken objective (one ProblemError line)."""

    def __init__(self, num_ants: int, batched: bool) -> None:
        self.num_ants = num_ants
        self.axis = 1 if batched else 0
        self.ran: np.ndarray | int = 0
        self.nan: np.ndarray | int = 0

    def add(self, hist: dict[str, Any]) -> None:
        if NAN_KEY not in hist:
            return
        counts = np.asarray(hist[NAN_KEY])
        self.ran = self.ran + np.where(counts >= 0, self.num_ants, 0).sum(axis=self.axis)
        self.nan = self.nan + np.where(counts >= 0, counts, 0).sum(axis=self.axis)

    def check(self, problem: Any) -> None:
        ran, nan = np.asarray(self.ran), np.asarray(self.nan)
        if np.any((ran > 0) & (nan >= ran)):
            name = getattr(problem, "name", type(problem).__name__)
            raise ProblemError(
                f"every evaluation of {name!r} returned NaN ({int(np.max(ran))} evaluations): "
                "its objective or constraints are NaN across the search box; check the "
                "function and its bounds")


def run(
    strategy: Strategy,
    problem: Any,
    state: State,
    *,
    total: int,
    chunk: int,
    seeds: list[int],
    rules: list[tuple[str, StopRule]] | None = None,
    progress: bool = False,
    checkpointing: Checkpointing | None = None,
    max_evaluations: int | None = None,
    compile_seconds: float = 0.0,
) -> Result:
    """Run ``state`` (one row per entry of ``seeds``) in chunks to ``total`` iterations
    (and, with ``max_evaluations``, until no row can start another iteration), or from the
    checkpoint of this same run in ``checkpointing.directory``. ``compile_seconds``: spent
    before (the initial state's program), counted in the result's."""
    batched = len(seeds) > 1
    capped = max_evaluations is not None
    budget = _budget_arg(max_evaluations)
    done = 0
    history: list[dict[str, Any]] = []  # chunks not yet in the checkpoint's history log
    tally = _NanTally(strategy.num_ants, batched)
    checkpointer = None
    every = None
    if checkpointing is not None:
        from eaco_jax.driver.checkpoint import RunCheckpointer, run_identity, strong_types

        state = strong_types(state)
        identity = run_identity(problem, strategy, state.params, seeds, total, chunk,
                                max_evaluations=max_evaluations)
        checkpointer = RunCheckpointer(
            checkpointing.directory, identity, every=checkpointing.every,
            seconds=checkpointing.seconds, keep=checkpointing.keep,
            run_info=checkpointing.run_info, batched=batched, chunk=chunk,
        )
        every = checkpointing.every
        try:
            restored = checkpointer.restore(state, on_segment=tally.add)
        except BaseException:
            checkpointer.close()
            raise
        if restored is not None:
            state, done = restored.state, restored.done
            chunk = checkpointer.chunk  # the chunk length the run was started with
            if restored.finished:
                total = done

    rules = rules or []
    run_seconds = 0.0
    start = done
    reason = "iterations"
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, initial=done, desc=getattr(problem, "name", "eaco"), unit="it")
    signals = _Signals(newline=bar is not None)
    try:
        with signals:
            while done < total:
                if capped and _exhausted(strategy, problem, state, max_evaluations):
                    reason = "max_evaluations"
                    break
                length = min(chunk, total - done)
                if every:  # saves land on multiples of checkpoint_every
                    length = min(length, every - done % every)
                signals.at = done
                try:
                    compiled, seconds = compiled_chunk(strategy, chunk, batched, problem, state,
                                                       capped, interrupted=signals)
                except _Interrupt:
                    reason = "interrupted"
                    break
                compile_seconds += seconds
                if signals():
                    reason = "interrupted"
                    break
                t0 = time.perf_counter()
                args = (problem, state, jnp.int32(length)) + ((budget,) if capped else ())
                signals.at = done + length
                try:
                    state, hist = compiled(*args)
                    jax.block_until_ready(state)
                except jax.errors.JaxRuntimeError as err:
                    oom = _out_of_memory(err, strategy, problem, len(seeds))
                    if oom is None:
                        raise
                    raise oom from None
                run_seconds += time.perf_counter() - t0
                chunk_hist = _trim(jax.device_get(hist), length, batched)
                history.append(chunk_hist)
                tally.add(chunk_hist)
                if capped and chunk_hist:  # the iterations any row ran (rows stop on budget)
                    length = next(iter(chunk_hist.values())).shape[1 if batched else 0]
                done += length
                tally.check(problem)
                if bar is not None:
                    bar.update(length)
                    bar.set_postfix(best=shown_best(problem, state.best_cost))
                info = Progress(done, run_seconds, compile_seconds)
                fired_names = [name for name, rule in rules if rule(state, info)]  # every rule
                if fired_names:  # sees every chunk (callbacks too)
                    reason = fired_names[0]
                elif capped and _exhausted(strategy, problem, state, max_evaluations):
                    reason = "max_evaluations"
                elif signals():
                    reason = "interrupted"
                stopping = reason != "iterations" or done >= total
                if checkpointer is not None and checkpointer.after_chunk(
                        state, done, history, finished=stopping and reason != "interrupted",
                        force=reason == "interrupted"):
                    history = []  # in the log now: memory stays flat however long the run
                if stopping:
                    break
            if reason == "interrupted" and checkpointer is not None and \
                    checkpointer.after_chunk(state, done, history, finished=False, force=True):
                history = []
    finally:
        if bar is not None:
            bar.close()
        if checkpointer is not None:
            checkpointer.close()
    if checkpointer is not None:  # the logged history, then what was not saved
        history = [checkpointer.history()] + history

    result = _result(strategy, problem, state, history, batched, seeds, reason,
                     compile_seconds, run_seconds, done - start, max_evaluations)
    if reason == "interrupted":
        raise Interrupted(_interrupt_message(signals.name or "SIGINT", result, done, total,
                                             checkpointing), result)
    return result


def _out_of_memory(err: Exception, strategy: Strategy, problem: Any,
                   rows: int) -> ConfigError | None:
    """A device out of memory in a chunk as one :class:`ConfigError` line (the last
    checkpoint stays as it was); None for any other runtime error (it keeps its traceback)."""
    text = str(err)
    if "RESOURCE_EXHAUSTED" not in text and "out of memory" not in text.lower():
        return None
    first = " ".join(text.split())[:160].rstrip(".")
    return ConfigError(
        f"out of memory running {type(strategy).__name__}(num_ants={strategy.num_ants}) on "
        f"{getattr(problem, 'name', type(problem).__name__)!r} ({rows} row(s)): {first}; use "
        "fewer ants or a smaller batch/chunk")


def _interrupt_message(name: str, result: Result, done: int, total: int,
                       checkpointing: Checkpointing | None) -> str:
    head = f"interrupted ({name}) after {done} of {total} iterations"
    if checkpointing is not None and done == 0:
        return f"{head}; nothing to save yet (start the same command again)"
    if checkpointing is not None:
        where = Path(checkpointing.directory)
        info = checkpointing.run_info or {}
        how = (f"eaco resume {where}" if info.get("kind") else
               "call minimize() again with the same Checkpointing")
        return f"{head}; checkpoint saved at step {done} in {where}; continue with: {how}"
    best = np.asarray(result.best_cost, np.float64).reshape(-1)
    shown = ", ".join(f"{b:.6g}" for b in best[:8]) + (", ..." if best.size > 8 else "")
    return f"{head}; best so far: {shown} (no checkpoint: pass --checkpoint-dir to resume)"


def _result(strategy: Strategy, problem: Any, state: State, history: list[dict[str, Any]],
            batched: bool, seeds: list[int], reason: str, compile_seconds: float,
            run_seconds: float, iters_here: int, max_evaluations: int | None) -> Result:
    """The :class:`Result`, with the returned solution re-checked on the host."""
    axis = 1 if batched else 0
    merged = merge_history(history, axis)
    merged.pop(NAN_KEY, None)
    iters_run = next(iter(merged.values())).shape[axis] if merged else 0
    best_solution = np.asarray(state.best_solution)
    best_cost = np.asarray(state.best_cost)
    checked = host_checks(problem, best_solution, batched)
    extra: dict[str, Any] = {}
    if checked:
        best_cost = _rows([c["cost"] for c in checked], batched)
        if "f" in checked[0]:
            extra["f"] = _rows([c["f"] for c in checked], batched)
            extra["violation"] = _rows([c["violation"] for c in checked], batched)
            extra["feasible"] = _rows([c["feasible"] for c in checked], batched, bool)
            extra["tolerance"] = checked[0].get("tolerance")
            _warn_feasibility(state, extra["feasible"], extra["f"], problem)
    dtypes = {x.dtype for x in _float_leaves(problem)}
    return Result(
        best_solution=best_solution,
        best_cost=best_cost,
        history=merged,
        iterations=iters_run,
        evaluations=np.asarray(state.evaluations),
        seconds=compile_seconds + run_seconds,
        compile_seconds=compile_seconds,
        seconds_per_iteration=run_seconds / max(iters_here, 1),
        state=state,
        problem=problem,
        strategy=strategy,
        seeds=seeds,
        stop_reason=reason,
        max_evaluations=max_evaluations,
        precision="float64" if np.dtype("float64") in dtypes else "float32",
        **extra,
    )


def _rows(values: list[Any], batched: bool, dtype: Any = np.float64) -> np.ndarray:
    a = np.asarray(values, dtype)
    return a if batched else a[0]


def host_checks(problem: Any, best_solution: np.ndarray, batched: bool) -> list[dict[str, Any]]:
    """``problem.host_check`` of every row's returned solution ([] if the problem has none).

    A returned solution that is not a solution (not a permutation, outside the bounds) is a
    bug in the strategy: it raises ``RuntimeError`` rather than report a wrong result.
    """
    check = getattr(problem, "host_check", None)
    if check is None:
        return []
    out = []
    for row in (best_solution if batched else best_solution[None]):
        try:
            out.append(check(row))
        except ProblemError as err:
            raise RuntimeError(
                f"the returned best solution is not a valid solution of "
                f"{getattr(problem, 'name', '')!r}: {err} (a bug; please report it)") from None
    return out


def _warn_feasibility(state: State, feasible: np.ndarray, f: np.ndarray, problem: Any) -> None:
    """One warning line where the reported best is no solution: its objective is not finite
    (the best of the least-violating evaluations was +inf, -inf or NaN), or a point feasible
    in the run's precision violates a constraint in float64."""
    f = np.asarray(f, np.float64)
    if not np.all(np.isfinite(f)):
        name = getattr(problem, "name", type(problem).__name__)
        worst = f[~np.isfinite(f)].reshape(-1)[0]
        which = ("with the least violation found " if int(getattr(problem, "num_inequality", 0))
                 + int(getattr(problem, "num_equality", 0)) else "")
        warnings.warn(
            f"every evaluation of {name!r} {which}returned {worst} (reported feasible=False): "
            "its objective is not finite across the search box; check the function and its "
            "bounds", stacklevel=3)
    v = getattr(state, "best_violation", None)
    if v is None:
        return
    claimed = np.asarray(v) <= 0
    if np.any(claimed & ~np.asarray(feasible) & np.isfinite(f)) and getattr(
            problem, "stochastic", False):
        warnings.warn(
            f"{getattr(problem, 'name', '')!r}: the best, feasible in the randomised worlds it "
            "was evaluated in, violates a constraint in the re-check's worlds (a robust "
            "search's best is noisy: choose among finalists on more worlds, e.g. eaco gait "
            "--finalists)", stacklevel=3)
    elif np.any(claimed & ~np.asarray(feasible) & np.isfinite(f)):
        warnings.warn(
            f"{getattr(problem, 'name', '')!r}: a point feasible in the run's precision violates "
            "a constraint when re-checked in float64; run with precision='float64' (or 'auto')",
            stacklevel=3)
