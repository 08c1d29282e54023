"""The run driver: many ask/evaluate/tell iterations inside ``lax.scan``, in compiled chunks.

One chunk of iterations is one compiled call (:mod:`~eaco_jax.driver.programs`); between
chunks the host updates the progress bar, asks :class:`~eaco_jax.driver.stopping.StopReason`
whether to stop and writes checkpoints (:class:`Checkpointing`). Several seeds, or several
hyper-parameter settings times seeds, run as one vmapped call (:mod:`~eaco_jax.driver.rows`).
This module is the loop; the rest of the driver is one idea per module: ``programs`` (the
compiled chunk and its lookup), ``rows`` (seeds x settings, Params, budgets), ``precision``,
``memory`` (checks before a run), ``interrupt`` (SIGINT / SIGTERM), ``stopping``, ``result``
(the :class:`Result` and the host-side re-checks). Their public names are re-exported here.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.driver import program_cache
from eaco_jax.driver.interrupt import CompileInterrupted, Signals, interrupt_message
from eaco_jax.driver.memory import (  # noqa: F401  (re-exported)
    GRAPH_ANT_CITY_BYTES,
    HESSIAN_MATRICES,
    LS_CANDIDATE_BYTES,
    LS_CITY_BYTES,
    WARN_WORKING_SET,
    check_state_memory,
    memory_limit,
    out_of_memory,
    state_row_bytes,
    working_set_bytes,
)
from eaco_jax.driver.precision import PRECISIONS, as_float64, needs_float64  # noqa: F401
from eaco_jax.driver.programs import (  # noqa: F401  (re-exported)
    NAN_KEY,
    RAN_KEY,
    budget_arg,
    clear_compiled,
    compiled_chunk,
    device_view,
    iteration_step,
    make_chunk_fn,
    signature,
)
from eaco_jax.driver.result import Result, host_checks, make_result, shown_best  # noqa: F401
from eaco_jax.driver.rows import (  # noqa: F401  (re-exported)
    MAX_EVALUATIONS,
    UNCAPPED,
    checked_seeds,
    compiled_initial,
    default_chunk,
    initial_state,
    initial_state_timed,
    resolve_iterations,
    stack_params,
)
from eaco_jax.driver.stop import Deadline, Progress, StopRule, WallTime
from eaco_jax.driver.stopping import StopReason, exhausted, stop_rules
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
    deadline: float | None = None,
    chunk_size: int | None = None,
    progress: bool = False,
    checkpointing: Checkpointing | None = None,
    precision: str = "auto",
    chunk_seconds: float | None = None,
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
      deadline: a ``time.monotonic()`` value: the run ends once the wall clock reaches it,
        checked before every chunk as well as after (stop reason ``"deadline"``, or
        ``"deadline_in_setup"`` when it passed before the first iteration: the result is
        then the initial state's best). A budget counted from the caller's start:
        ``deadline=started + seconds``.
      chunk_size: iterations per compiled call (default: about 20 chunks per run).
      chunk_seconds: pace the chunks: each runs as many of its ``chunk_size`` iterations as
        take about this many compute seconds at the previous chunk's pace, and no more than
        fit in what a time rule (``max_seconds``, ``deadline``) leaves; the first runs one.
        For runs whose iterations take milliseconds: fewer host round trips between them,
        the clock still read every ``chunk_seconds`` (None: every chunk runs in full).
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
    if chunk_seconds is not None and (isinstance(chunk_seconds, bool) or not isinstance(
            chunk_seconds, int | float) or not (math.isfinite(chunk_seconds)
                                                 and chunk_seconds > 0)):
        raise ConfigError(f"chunk_seconds must be a finite number > 0 (or None), got "
                          f"{chunk_seconds!r}")
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
        if rows > 1 and hasattr(problem, "for_rows"):  # buffers shared by the vmapped rows
            problem = problem.for_rows(rows)
        rules = stop_rules(target, patience, max_seconds, callback, stop, deadline)
        if params is None:
            params = strategy.default_params(problem)
        init, init_args, init_seconds = compiled_initial(strategy, problem, seeds, params)
        check_state_memory(strategy, problem, rows, params,
                           state_bytes=program_cache.out_nbytes(init))
        state = init(*init_args)
        row_seeds = seeds * n_settings
        return run(strategy, problem, state, total=total, chunk=chunk, seeds=row_seeds,
                   rules=rules, progress=progress, checkpointing=checkpointing,
                   max_evaluations=max_evaluations, compile_seconds=init_seconds,
                   chunk_seconds=chunk_seconds)


def time_left(rules: list[tuple[str, StopRule]], progress: Progress) -> float | None:
    """Seconds the time rules (``max_seconds``: compute; ``deadline``: wall clock) leave
    after ``progress``; None without such a rule."""
    left = [rule.seconds - progress.seconds for _, rule in rules if isinstance(rule, WallTime)]
    left += [rule.at - progress.now for _, rule in rules if isinstance(rule, Deadline)]
    return min(left) if left else None


def paced_length(pace: float | None, seconds: float, left: float | None) -> int:
    """Iterations for the next chunk: about ``seconds`` of compute at ``pace`` seconds an
    iteration, no more than fit in ``left`` (None: no time rule), at least one; one while
    the pace is unknown."""
    if pace is None or pace <= 0:
        return 1
    fit = seconds if left is None else min(seconds, left)
    return max(1, int(fit / pace))


def _trim(hist: dict[str, Any], length: int, batched: bool) -> dict[str, np.ndarray]:
    """The chunk's history up to ``length`` (and, for capped runs, the last iteration any
    row ran), without the ``_ran`` column."""
    ran = hist.get(RAN_KEY)
    if ran is not None:
        ran = np.asarray(ran)
        any_ran = ran.any(axis=0) if batched else ran
        idx = np.flatnonzero(any_ran[:length])
        length = int(idx[-1]) + 1 if idx.size else 0
    cut = (slice(None), slice(length)) if batched else (slice(length),)
    return {k: np.asarray(v)[cut] for k, v in hist.items() if k != RAN_KEY}


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
    chunk_seconds: float | None = None,
) -> Result:
    """Run ``state`` (one row per entry of ``seeds``) in chunks to ``total`` iterations
    (and, with ``max_evaluations``, until no row can start another iteration), or from the
    checkpoint of this same run in ``checkpointing.directory``. ``compile_seconds``: spent
    before (the initial state's program), counted in the result's."""
    batched = len(seeds) > 1
    capped = max_evaluations is not None
    budget = budget_arg(max_evaluations)
    device = device_view(problem)  # what the compiled chunks take
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

    run_seconds = 0.0
    pace = None  # compute seconds per iteration of the last chunk
    reuse = None  # the compiled chunk, once its output state matched its input's shapes
    lengths: dict[int, jax.Array] = {}  # chunk lengths as device scalars, made once each
    start = done
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=None if total >= UNCAPPED else total, initial=done,
                   desc=getattr(problem, "name", "eaco"), unit="it")
    signals = Signals(newline=bar is not None)
    loop_from, compiled_before = time.perf_counter(), compile_seconds  # for host_seconds
    stopping = StopReason(rules or [], total, interrupted=signals,
                          exhausted=lambda s: exhausted(strategy, problem, s, max_evaluations))
    try:
        with signals:
            while (reason := stopping.before_chunk(
                    state, done, Progress(done, run_seconds, compile_seconds))) is None:
                length = min(chunk, total - done)
                if every:  # saves land on multiples of checkpoint_every
                    length = min(length, every - done % every)
                if chunk_seconds is not None:
                    length = min(length, paced_length(
                        pace, chunk_seconds,
                        time_left(rules or [], Progress(done, run_seconds, compile_seconds))))
                signals.at = done
                if reuse is not None:  # the state keeps its shapes: no lookup per chunk
                    compiled, seconds = reuse, 0.0
                else:
                    try:
                        compiled, seconds = compiled_chunk(strategy, chunk, batched, device,
                                                           state, capped, interrupted=signals)
                    except CompileInterrupted:
                        continue  # the stop reason sees the signal
                compile_seconds += seconds
                # a deadline may pass while compiling (not cut short: an abandoned compiler
                # thread can crash the interpreter's exit)
                now = Progress(done, run_seconds, compile_seconds)
                if signals() or (seconds > 0 and stopping.before_chunk(state, done, now)):
                    continue
                t0 = time.perf_counter()
                if length not in lengths:
                    lengths[length] = jnp.int32(length)
                args = (device, state, lengths[length]) + ((budget,) if capped else ())
                signals.at = done + length
                try:
                    before = state
                    state, hist = compiled(*args)
                    jax.block_until_ready(state)
                    if reuse is None and signature(state) == signature(before):
                        reuse = compiled
                except jax.errors.JaxRuntimeError as err:
                    oom = out_of_memory(err, strategy, problem, len(seeds))
                    if oom is None:
                        raise
                    raise oom from None
                ran = time.perf_counter() - t0
                run_seconds += ran
                pace = ran / length
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
                reason = stopping.after_chunk(state, Progress(done, run_seconds, compile_seconds))
                if checkpointer is not None and checkpointer.after_chunk(
                        state, done, history, finished=reason not in (None, "interrupted"),
                        force=reason == "interrupted"):
                    history = []  # in the log now: memory stays flat however long the run
                if reason is not None:
                    break
            if reason == "interrupted" and checkpointer is not None and \
                    checkpointer.after_chunk(state, done, history, finished=False, force=True):
                history = []
    finally:
        if bar is not None:
            bar.close()
        if checkpointer is not None:
            checkpointer.close()
    loop_wall = time.perf_counter() - loop_from
    host_seconds = max(loop_wall - run_seconds - (compile_seconds - compiled_before), 0.0)
    if checkpointer is not None:  # the logged history, then what was not saved
        history = [checkpointer.history()] + history

    result = make_result(strategy, problem, state, history, batched, seeds, reason,
                         compile_seconds, run_seconds, done - start, max_evaluations,
                         host_seconds)
    if reason == "interrupted":
        raise Interrupted(interrupt_message(signals.name or "SIGINT", result, done, total,
                                            checkpointing), result)
    return result
