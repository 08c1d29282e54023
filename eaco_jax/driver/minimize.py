"""The run driver: many ask/evaluate/tell iterations inside ``lax.scan``, in compiled chunks.

One chunk of iterations is one compiled call; between chunks the host updates the progress
bar, asks the stop rules (:mod:`eaco_jax.driver.stop`) and writes checkpoints
(:class:`Checkpointing`). Several seeds, or several hyper-parameter settings times seeds, run
as one vmapped call. Compiled chunks are cached: a second ``minimize`` with the same strategy,
shapes and chunk length compiles nothing.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.driver.history import merge_history
from eaco_jax.driver.stop import Callback, Patience, Progress, StopRule, Target, WallTime
from eaco_jax.errors import ConfigError, ProblemError
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
    iteration mean, diversity, plus strategy-specific metrics). ``stop_reason`` says why the
    run ended: ``"iterations"`` (the budget) or the name of the stop rule that fired.
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

    @property
    def batched(self) -> bool:
        return len(self.seeds) > 1 or np.ndim(self.best_cost) > 0

    # best solution, objective, violation (strategies with constraints keep best_f /
    # best_violation in their state; graph problems have no constraints)
    @property
    def x(self) -> np.ndarray:
        return self.best_solution

    @property
    def f(self) -> np.ndarray:
        return np.asarray(getattr(self.state, "best_f", self.best_cost))

    @property
    def violation(self) -> np.ndarray:
        v = getattr(self.state, "best_violation", None)
        return np.zeros_like(self.best_cost) if v is None else np.asarray(v)

    @property
    def feasible(self) -> np.ndarray:
        return self.violation <= 0


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
    raise ProblemError(
        "minimize() needs a problem with kind 'graph', 'path' or 'continuous', got "
        f"{type(problem).__name__} with kind={kind!r}; "
        "build one with eaco_jax.problems (TSP, ConstrainedProblem, ...)."
    )


# --------------------------------------------------------------------------- one iteration
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
    return strategy.tell(state, solutions, fitness, problem)


def make_chunk_fn(strategy: Strategy, length: int, batched: bool) -> Callable:
    """A jitted ``(problem, state, active) -> (state, history)`` over ``length`` iterations.

    Only the first ``active`` (a traced int) iterations run; the rest pass the state through
    (``lax.cond``), so a run's last, shorter chunk reuses the same compiled program. The
    caller drops the history rows past ``active``.
    """

    def run(problem, state, active):
        def step(s, i):
            def skip(s):
                shapes = jax.eval_shape(lambda t: iteration_step(strategy, problem, t)[1], s)
                return s, jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype), shapes)

            return jax.lax.cond(i < active, lambda s: iteration_step(strategy, problem, s),
                                skip, s)

        return jax.lax.scan(step, state, jnp.arange(length))

    if batched:
        run = jax.vmap(run, in_axes=(None, 0, None))
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


def compiled_chunk(strategy: Strategy, length: int, batched: bool, problem: Any,
                   state: State) -> tuple[Any, float]:
    """The compiled chunk for these shapes and static configuration, and the seconds spent
    compiling it now (0.0 when it came from this process's cache)."""
    key = (strategy, length, batched, _signature(problem), _signature(state))
    if key in _COMPILED:
        _COMPILED.move_to_end(key)
        return _COMPILED[key], 0.0
    t0 = time.perf_counter()
    active = jnp.int32(length)
    compiled = make_chunk_fn(strategy, length, batched).lower(problem, state, active).compile()
    seconds = time.perf_counter() - t0
    _COMPILED[key] = compiled
    while len(_COMPILED) > _COMPILED_MAX:
        _COMPILED.popitem(last=False)
    return compiled, seconds


# --------------------------------------------------------------------------- setup helpers
def initial_state(
    strategy: Strategy, problem: Any, seeds: Sequence[int], params: Any | None = None
) -> State:
    """The initial state for one seed, or a vmapped batch of states.

    ``params`` is one Params pytree (default: ``strategy.default_params(problem)``) or a list
    of them (a batch of settings): then row ``r`` belongs to ``params[r // len(seeds)]`` with
    seed ``seeds[r % len(seeds)]``.
    """
    if isinstance(params, list | tuple):
        stacked = stack_params(list(params))
        flat = jax.tree.map(lambda x: jnp.repeat(x, len(seeds), axis=0), stacked)
        keys = jnp.stack([jax.random.key(int(s)) for s in list(seeds) * len(params)])
        return jax.vmap(lambda k, p: strategy.init(k, problem, p))(keys, flat)
    keys = jnp.stack([jax.random.key(int(s)) for s in seeds])
    if params is None:
        params = strategy.default_params(problem)
    if len(seeds) == 1:
        return strategy.init(keys[0], problem, params)
    return jax.vmap(lambda k: strategy.init(k, problem, params))(keys)


def stack_params(params: Sequence[Any]) -> Any:
    """Stack a list of same-structure Params pytrees along a new leading axis."""
    if not params:
        raise ConfigError("params sequence is empty")
    structures = {str(jax.tree_util.tree_structure(p)) for p in params}
    if len(structures) > 1:
        raise ConfigError("every params set must have the same fields (one Params type)")
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *params)


def resolve_iterations(
    strategy: Strategy, iterations: int | None, max_evaluations: int | None
) -> int:
    """The iteration budget from ``iterations`` or ``max_evaluations`` (default 100)."""
    if iterations is not None and max_evaluations is not None:
        raise ConfigError("give iterations or max_evaluations, not both")
    if max_evaluations is not None:
        if max_evaluations < strategy.num_ants:
            raise ConfigError(
                f"max_evaluations={max_evaluations} is below one colony ({strategy.num_ants} ants)"
            )
        return max_evaluations // strategy.num_ants
    iterations = 100 if iterations is None else iterations
    if iterations < 1:
        raise ConfigError(f"iterations must be >= 1, got {iterations}")
    return int(iterations)


def checked_seeds(strategy: Strategy, problem: Any, seed: int | Sequence[int]) -> list[int]:
    """The seeds as a list, after checking that ``strategy`` solves ``problem``'s kind."""
    kind = getattr(problem, "kind", None)
    if strategy.problem_kind and kind != strategy.problem_kind:
        raise ProblemError(
            f"{type(strategy).__name__} solves '{strategy.problem_kind}' problems, "
            f"but {getattr(problem, 'name', problem)!r} is '{kind}'"
        )
    seeds = [int(seed)] if np.ndim(seed) == 0 else [int(s) for s in seed]
    if not seeds:
        raise ConfigError("seed sequence is empty")
    return seeds


def default_chunk(total: int, chunk_size: int | None, checkpoint_every: int | None) -> int:
    """Iterations per compiled call: given, else ~20 chunks per run, at most checkpoint_every."""
    if chunk_size is not None:
        if chunk_size < 1:
            raise ConfigError(f"chunk_size must be >= 1, got {chunk_size}")
        return int(chunk_size)
    chunk = max(1, math.ceil(total / 20))
    return min(chunk, int(checkpoint_every)) if checkpoint_every else chunk


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
        rules.append(("target", Target(float(target))))
    if patience is not None:
        rules.append(("patience", Patience(int(patience))))
    if max_seconds is not None:
        if not max_seconds > 0:
            raise ConfigError(f"max_seconds must be > 0, got {max_seconds}")
        rules.append(("max_seconds", WallTime(float(max_seconds))))
    if callback is not None:
        rules.append(("callback", Callback(callback)))
    if stop is not None:
        for r in ([stop] if callable(stop) else list(stop)):
            rules.append((getattr(r, "__name__", type(r).__name__), r))
    return rules


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
) -> Result:
    """Minimise ``problem`` with an EACO colony (or any strategy of the library).

    Args:
      problem: a graph, path or continuous problem (see :mod:`eaco_jax.problems`).
      strategy: the colony; default :func:`default_strategy` for the problem's kind.
      seed: an int, or a sequence of ints to run several seeds as one vmapped call.
      params: hyper-parameters (default ``strategy.default_params(problem)``), or a list of
        Params to run every setting x every seed as one vmapped call (row ``r`` is
        ``params[r // len(seeds)]`` with seed ``seeds[r % len(seeds)]``).
      iterations / max_evaluations: the budget (one of them; default 100 iterations).
      target / patience / max_seconds / callback / stop: stop rules, checked after every
        chunk (see :mod:`eaco_jax.driver.stop`): every row's best <= target; every row
        stagnated ``patience`` iterations; compute seconds (compilation excluded);
        ``callback(state, progress)`` returned True; any further ``rule(state, progress)``.
      chunk_size: iterations per compiled call (default: about 20 chunks per run).
      progress: show a progress bar (tqdm).
      checkpointing: save (and resume) the run, see :class:`Checkpointing`.
    """
    strategy = default_strategy(problem) if strategy is None else strategy
    seeds = checked_seeds(strategy, problem, seed)
    problem = strategy.prepare(problem)
    total = resolve_iterations(strategy, iterations, max_evaluations)
    every = checkpointing.every if checkpointing is not None else None
    chunk = default_chunk(total, chunk_size, every)
    rows = len(seeds) * (len(params) if isinstance(params, list | tuple) else 1)
    rules = stop_rules(target, patience, max_seconds, callback, stop)
    state = initial_state(strategy, problem, seeds, params)
    row_seeds = seeds * (rows // len(seeds))
    return run(strategy, problem, state, total=total, chunk=chunk, seeds=row_seeds,
               rules=rules, progress=progress, checkpointing=checkpointing)


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
) -> Result:
    """Run ``state`` (one row per entry of ``seeds``) in chunks to ``total`` iterations, or
    from the checkpoint of this same run in ``checkpointing.directory``."""
    batched = len(seeds) > 1
    done, history = 0, []
    checkpointer = None
    if checkpointing is not None:
        from eaco_jax.driver.checkpoint import RunCheckpointer, run_identity, strong_types

        state = strong_types(state)
        identity = run_identity(problem, strategy, state.params, seeds, total, chunk)
        checkpointer = RunCheckpointer(
            checkpointing.directory, identity, every=checkpointing.every,
            seconds=checkpointing.seconds, keep=checkpointing.keep,
            run_info=checkpointing.run_info, batched=batched,
        )
        restored = checkpointer.restore(state)
        if restored is not None:
            state, done, history = restored.state, restored.done, [restored.history]
            if restored.finished:
                total = done

    rules = rules or []
    compile_seconds = run_seconds = 0.0
    start = done
    reason = "iterations"
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, initial=done, desc=getattr(problem, "name", "eaco"), unit="it")
    try:
        while done < total:
            length = min(chunk, total - done)
            compiled, seconds = compiled_chunk(strategy, chunk, batched, problem, state)
            compile_seconds += seconds
            t0 = time.perf_counter()
            state, hist = compiled(problem, state, jnp.int32(length))
            jax.block_until_ready(state)
            run_seconds += time.perf_counter() - t0
            hist = jax.device_get(hist)
            time_axis = (slice(None), slice(length)) if batched else (slice(length),)
            history.append({k: np.asarray(v)[time_axis] for k, v in hist.items()})
            done += length
            if bar is not None:
                bar.update(length)
                bar.set_postfix(best=float(np.min(np.asarray(state.best_cost))))
            info = Progress(done, run_seconds, compile_seconds)
            fired_names = [name for name, rule in rules if rule(state, info)]  # every rule sees
            fired = bool(fired_names)  # every chunk (callbacks too)
            if fired:
                reason = fired_names[0]
            if checkpointer is not None:
                checkpointer.after_chunk(state, done, history, finished=fired or done >= total)
            if fired:
                break
    finally:
        if bar is not None:
            bar.close()

    axis = 1 if batched else 0
    merged = merge_history(history, axis)
    iters_run = next(iter(merged.values())).shape[axis] if merged else 0
    return Result(
        best_solution=np.asarray(state.best_solution),
        best_cost=np.asarray(state.best_cost),
        history=merged,
        iterations=iters_run,
        evaluations=np.asarray(state.evaluations),
        seconds=compile_seconds + run_seconds,
        compile_seconds=compile_seconds,
        seconds_per_iteration=run_seconds / max(done - start, 1),
        state=state,
        problem=problem,
        strategy=strategy,
        seeds=seeds,
        stop_reason=reason,
    )
