"""The run driver: many ask/evaluate/tell iterations inside ``lax.scan``, in chunks.

One chunk of iterations is one compiled call; between chunks the host updates the progress
bar, checks the stop conditions and (see :mod:`eaco_jax.driver.checkpoint`) writes
checkpoints. Several
seeds run as one vmapped call when ``seed`` is a sequence.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.strategies.base import State, Strategy


@dataclasses.dataclass
class Result:
    """What :func:`minimize` returns. With several seeds every array has a leading seed axis.

    ``history`` maps a statistic name to an array over iterations (best so far, iteration
    best, iteration mean, diversity, plus strategy-specific entries).
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
    raise TypeError(
        "minimize() needs a problem with kind 'graph', 'path' or 'continuous', got "
        f"{type(problem).__name__} with kind={kind!r}; "
        "build one with eaco_jax.problems (TSP, ConstrainedProblem, ...)."
    )


def iteration_step(strategy: Strategy, problem: Any, state: State) -> tuple[State, dict]:
    """One ask -> evaluate -> tell round; the key for it is split off ``state.key``."""
    key, ask_key = jax.random.split(state.key)
    solutions, state = strategy.ask(ask_key, state.replace(key=key))
    fitness = problem.evaluate(solutions)
    state = strategy.tell(state, solutions, fitness)
    return state, strategy.stats(state)


def make_chunk_fn(strategy: Strategy, length: int, batched: bool) -> Callable:
    """A jitted ``(problem, state, active=None) -> (state, history)`` over ``length`` iterations.

    With ``active`` (a traced int) only the first ``active`` iterations run and the rest pass the
    state through (``lax.cond``), so a run's last, shorter chunk reuses the same compiled program
    instead of compiling another; the caller drops the history rows past ``active``.
    """

    def run(problem, state, active):
        def step(s, i):
            if active is None:
                return iteration_step(strategy, problem, s)
            return jax.lax.cond(
                i < active,
                lambda s: iteration_step(strategy, problem, s),
                lambda s: (s, strategy.stats(s)),
                s,
            )

        return jax.lax.scan(step, state, jnp.arange(length))

    if batched:
        run = jax.vmap(run, in_axes=(None, 0, None))

    def chunk(problem, state, active=None):
        return run(problem, state, active)

    return jax.jit(chunk)


def init_states(
    strategy: Strategy, problem: Any, seeds: Sequence[int], params: Any | None
) -> State:
    """Initial state for one seed, or a vmapped batch of states for several."""
    keys = jnp.stack([jax.random.key(int(s)) for s in seeds])
    if params is None:
        params = strategy.default_params(problem)
    if len(seeds) == 1:
        return strategy.init(keys[0], problem, params)
    return jax.vmap(lambda k: strategy.init(k, problem, params))(keys)


def resolve_iterations(
    strategy: Strategy, iterations: int | None, max_evaluations: int | None
) -> int:
    if iterations is not None and max_evaluations is not None:
        raise ValueError("give iterations or max_evaluations, not both")
    if max_evaluations is not None:
        if max_evaluations < strategy.num_ants:
            raise ValueError(
                f"max_evaluations={max_evaluations} is below one colony ({strategy.num_ants} ants)"
            )
        return max_evaluations // strategy.num_ants
    iterations = 100 if iterations is None else iterations
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    return int(iterations)


def checked_seeds(strategy: Strategy, problem: Any, seed: int | Sequence[int]) -> list[int]:
    """The seeds as a list, after checking that ``strategy`` solves ``problem``'s kind."""
    kind = getattr(problem, "kind", None)
    if strategy.problem_kind and kind != strategy.problem_kind:
        raise TypeError(
            f"{type(strategy).__name__} solves '{strategy.problem_kind}' problems, "
            f"but {getattr(problem, 'name', problem)!r} is '{kind}'"
        )
    seeds = [int(seed)] if np.ndim(seed) == 0 else [int(s) for s in seed]
    if not seeds:
        raise ValueError("seed sequence is empty")
    return seeds


def minimize(
    problem: Any,
    strategy: Strategy | None = None,
    *,
    seed: int | Sequence[int] = 0,
    iterations: int | None = None,
    max_evaluations: int | None = None,
    params: Any | None = None,
    chunk_size: int | None = None,
    target: float | None = None,
    progress: bool = False,
    on_chunk: Callable[[State, int], None] | None = None,
    checkpoint_dir: str | Path | None = None,
    checkpoint_every: int | None = None,
    checkpoint_seconds: float | None = None,
    keep: int = 3,
    run_info: dict[str, Any] | None = None,
) -> Result:
    """Minimise ``problem`` with an EACO colony.

    Args:
      problem: a graph or continuous problem (see :mod:`eaco_jax.problems.base`).
      strategy: the colony; default :func:`default_strategy` for the problem's kind.
      seed: an int, or a sequence of ints to run several seeds as one vmapped call.
      iterations / max_evaluations: the budget (one of them; default 100 iterations).
      params: hyper-parameters (default ``strategy.default_params(problem)``).
      chunk_size: iterations per compiled call (default: about 20 chunks per run).
      target: stop after the chunk in which every seed's best cost is <= target.
      progress: show a progress bar (tqdm).
      on_chunk: called as ``on_chunk(state, iterations_done)`` after each chunk.
      checkpoint_dir: save the run there (see :mod:`eaco_jax.driver.checkpoint`); when the folder
        already holds a checkpoint of this same run, continue from its newest complete step
        (bit-identical to an unbroken run). A checkpoint of another run raises CheckpointError.
      checkpoint_every / checkpoint_seconds: save after the chunk in which this many iterations
        / seconds have passed since the last save (the end of the run is always saved).
        ``checkpoint_every`` also caps the default chunk length so saves land on it.
      keep: how many checkpoints to keep.
      run_info: JSON-able dict stored with each checkpoint (``eaco resume`` reads
        ``{"command": name, "args": {...}}`` from it).
    """
    strategy = default_strategy(problem) if strategy is None else strategy
    seeds = checked_seeds(strategy, problem, seed)
    total = resolve_iterations(strategy, iterations, max_evaluations)
    chunk = default_chunk(total, chunk_size, checkpoint_every)
    batched = len(seeds) > 1

    state = init_states(strategy, problem, seeds, params)
    return run_resumable(
        strategy, problem, state, total=total, chunk=chunk, batched=batched, seeds=seeds,
        target=target, progress=progress, on_chunk=on_chunk, checkpoint_dir=checkpoint_dir,
        checkpoint_every=checkpoint_every, checkpoint_seconds=checkpoint_seconds, keep=keep,
        run_info=run_info,
    )


def stack_params(params: Sequence[Any]) -> Any:
    """Stack a list of same-structure Params pytrees along a new leading axis."""
    if not params:
        raise ValueError("params sequence is empty")
    structures = {str(jax.tree_util.tree_structure(p)) for p in params}
    if len(structures) > 1:
        raise ValueError("every params set must have the same fields (one Params type)")
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *params)


def minimize_batch(
    problem: Any,
    strategy: Strategy,
    params: Sequence[Any],
    *,
    seed: int | Sequence[int] = 0,
    iterations: int | None = None,
    max_evaluations: int | None = None,
    chunk_size: int | None = None,
    progress: bool = False,
    checkpoint_dir: str | Path | None = None,
    checkpoint_every: int | None = None,
    checkpoint_seconds: float | None = None,
    keep: int = 3,
    run_info: dict[str, Any] | None = None,
) -> Result:
    """Several hyper-parameter sets x seeds as ONE vmapped, jitted run (a sweep on one device).

    Hyper-parameters are traced (they live in ``state.params``), so every (params, seed) pair is
    one row of a batch of colony states. Row ``r`` of every result array belongs to
    ``params[r // len(seeds)]`` with seed ``seeds[r % len(seeds)]``; ``result.seeds`` lists the
    seed of every row. Checkpointing works as in :func:`minimize`.
    """
    seeds = checked_seeds(strategy, problem, seed)
    stacked = stack_params(list(params))
    rows = len(params) * len(seeds)
    flat = jax.tree.map(lambda x: jnp.repeat(x, len(seeds), axis=0), stacked)
    keys = jnp.stack([jax.random.key(s) for s in seeds * len(params)])
    state = jax.vmap(lambda k, p: strategy.init(k, problem, p))(keys, flat)
    total = resolve_iterations(strategy, iterations, max_evaluations)
    chunk = default_chunk(total, chunk_size, checkpoint_every)
    assert state.iteration.shape == (rows,)
    return run_resumable(
        strategy, problem, state, total=total, chunk=chunk, batched=True,
        seeds=seeds * len(params), progress=progress, checkpoint_dir=checkpoint_dir,
        checkpoint_every=checkpoint_every, checkpoint_seconds=checkpoint_seconds, keep=keep,
        run_info=run_info,
    )


def default_chunk(total: int, chunk_size: int | None, checkpoint_every: int | None) -> int:
    """Iterations per compiled call: given, else ~20 chunks per run, at most checkpoint_every."""
    if chunk_size is not None:
        if chunk_size < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size}")
        return int(chunk_size)
    chunk = max(1, math.ceil(total / 20))
    return min(chunk, int(checkpoint_every)) if checkpoint_every else chunk


def run_resumable(
    strategy: Strategy,
    problem: Any,
    state: State,
    *,
    total: int,
    chunk: int,
    batched: bool,
    seeds: list[int],
    target: float | None = None,
    progress: bool = False,
    on_chunk: Callable[[State, int], None] | None = None,
    checkpoint_dir: str | Path | None = None,
    checkpoint_every: int | None = None,
    checkpoint_seconds: float | None = None,
    keep: int = 3,
    run_info: dict[str, Any] | None = None,
) -> Result:
    """:func:`run_chunks` from a fresh ``state``, or from the checkpoint in ``checkpoint_dir``."""
    if checkpoint_dir is None:
        if checkpoint_every is not None or checkpoint_seconds is not None:
            raise ValueError("checkpoint_every / checkpoint_seconds need a checkpoint_dir")
        return run_chunks(
            strategy, problem, state, total=total, chunk=chunk, batched=batched, seeds=seeds,
            target=target, progress=progress, on_chunk=on_chunk,
        )
    from eaco_jax.driver.checkpoint import RunCheckpointer, run_identity, strong_types

    state = strong_types(state)
    identity = run_identity(problem, strategy, state.params, seeds, total, chunk)
    ckpt = RunCheckpointer(
        checkpoint_dir, identity, every=checkpoint_every, seconds=checkpoint_seconds,
        keep=keep, run_info=run_info, batched=batched,
    )
    restored = ckpt.restore(state)
    done, history = 0, None
    if restored is not None:
        state, done, history = restored.state, restored.done, [restored.history]
        if restored.finished:
            total = done
    return run_chunks(
        strategy, problem, state, total=total, chunk=chunk, batched=batched, seeds=seeds,
        done=done, history=history, target=target, progress=progress, on_chunk=on_chunk,
        checkpointer=ckpt,
    )


def run_chunks(
    strategy: Strategy,
    problem: Any,
    state: State,
    *,
    total: int,
    chunk: int,
    batched: bool,
    seeds: list[int],
    done: int = 0,
    history: list[dict] | None = None,
    target: float | None = None,
    progress: bool = False,
    on_chunk: Callable[[State, int], None] | None = None,
    checkpointer: Any | None = None,
) -> Result:
    """Run chunks from iteration ``done`` to ``total`` (used by minimize and by resume).

    ``checkpointer`` (a :class:`eaco_jax.checkpoint.RunCheckpointer`) is offered every chunk
    boundary; it saves when due and always after the last chunk.
    """
    history = [] if history is None else history
    compiled: Any = None
    compile_seconds = 0.0
    run_seconds = 0.0
    start = done
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=total, initial=done, desc=getattr(problem, "name", "eaco"), unit="it")
    try:
        while done < total:
            length = min(chunk, total - done)
            active = jnp.int32(length)
            if compiled is None:
                t0 = time.perf_counter()
                fn = make_chunk_fn(strategy, chunk, batched)
                compiled = fn.lower(problem, state, active).compile()
                compile_seconds += time.perf_counter() - t0
            t0 = time.perf_counter()
            state, hist = compiled(problem, state, active)
            jax.block_until_ready(state)
            run_seconds += time.perf_counter() - t0
            hist = jax.device_get(hist)
            time_axis = (slice(None), slice(length)) if batched else (slice(length),)
            history.append({k: np.asarray(v)[time_axis] for k, v in hist.items()})
            done += length
            if bar is not None:
                bar.update(length)
                bar.set_postfix(best=float(np.min(np.asarray(state.best_cost))))
            if on_chunk is not None:
                on_chunk(state, done)
            reached = target is not None and bool(np.all(np.asarray(state.best_cost) <= target))
            if checkpointer is not None:
                checkpointer.after_chunk(state, done, history, finished=reached or done >= total)
            if reached:
                break
    finally:
        if bar is not None:
            bar.close()

    axis = 1 if batched else 0
    merged = {
        k: np.concatenate([np.asarray(h[k]) for h in history], axis=axis) for k in history[0]
    } if history else {}
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
    )
