"""Rows: the seeds x settings a call runs as one vmapped batch, their checked seeds and Params,
the initial state, and the budget's integers (iterations, evaluations, chunk length)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.driver.programs import compiled_init, device_view
from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.strategies.base import State, Strategy


def initial_state(
    strategy: Strategy, problem: Any, seeds: Sequence[int], params: Any | None = None
) -> State:
    """The initial state for one seed, or a vmapped batch of states.

    ``params`` is one Params pytree (default: ``strategy.default_params(problem)``) or a list
    of them (a batch of settings): then row ``r`` belongs to ``params[r // len(seeds)]`` with
    seed ``seeds[r % len(seeds)]``. Concrete params are checked against their ranges first.
    """
    return initial_state_timed(strategy, problem, seeds, params)[0]


def initial_state_timed(strategy: Strategy, problem: Any, seeds: Sequence[int],
                        params: Any | None = None) -> tuple[State, float]:
    """:func:`initial_state` and the seconds spent compiling (or loading) its program."""
    init, args, seconds = compiled_initial(strategy, problem, seeds, params)
    return init(*args), seconds


def compiled_initial(strategy: Strategy, problem: Any, seeds: Sequence[int],
                     params: Any | None = None) -> tuple[Any, tuple, float]:
    """The compiled (or loaded) initialiser of :func:`initial_state`, its arguments (call
    ``init(*args)`` for the state) and the seconds spent on it now; nothing is run, so the
    state's size can be checked from the program before anything is allocated."""
    problem = strategy.prepare(problem)
    device = device_view(problem)  # what the compiled initialiser takes
    if isinstance(params, list | tuple):
        for i, p in enumerate(params):
            strategy.check_params(p, where=f"params[{i}]: " if len(params) > 1 else "")
        stacked = stack_params(list(params))
        flat = jax.tree.map(lambda x: jnp.repeat(x, len(seeds), axis=0), stacked)
        keys = jnp.stack([jax.random.key(int(s)) for s in list(seeds) * len(params)])
        init, seconds = compiled_init(strategy, "per_row", device, keys, flat)
        return init, (keys, device, flat), seconds
    keys = jnp.stack([jax.random.key(int(s)) for s in seeds])
    if params is None:
        params = strategy.default_params(problem)
    strategy.check_params(params)
    rows = "one" if len(seeds) == 1 else "shared"
    init, seconds = compiled_init(strategy, rows, device, keys, params)
    return init, (keys, device, params), seconds


def stack_params(params: Sequence[Any]) -> Any:
    """Stack a list of same-structure Params pytrees along a new leading axis."""
    if not params:
        raise ConfigError("params sequence is empty")
    structures = {str(jax.tree_util.tree_structure(p)) for p in params}
    if len(structures) > 1:
        raise ConfigError("every params set must have the same fields (one Params type)")
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *params)


#: an iteration budget this large is no cap: the run of ``--max-seconds`` alone, which time
#: (or another stop rule) ends
UNCAPPED = 2**31 - 1

#: evaluation counters are int32
MAX_EVALUATIONS = 2**31 - 1 - 2**24


def count(name: str, value: Any, low: int = 1, high: int = 2**31 - 1) -> int:
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
        budget = count("max_evaluations", max_evaluations, 1, MAX_EVALUATIONS)
        per_iteration = strategy.max_charge(problem)
        if budget < per_iteration:
            raise ConfigError(
                f"max_evaluations={budget} is below what one iteration can charge "
                f"({per_iteration}: {strategy.charge_note(problem)}); raise it or use fewer ants")
        return max(1, budget // strategy.num_ants)
    iterations = 100 if iterations is None else iterations
    return count("iterations", iterations, 1, 2**31 - 1)


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
    return [count("seed", s, 0, 2**32 - 1) for s in raw]


def default_chunk(total: int, chunk_size: int | None, checkpoint_every: int | None = None) -> int:
    """Iterations per compiled call: given, else ~20 chunks per run.

    (Checkpoints cut chunks short where they are due, so ``checkpoint_every`` no longer
    changes the chunk length; the argument is kept for callers.)
    """
    if chunk_size is not None:
        return count("chunk_size", chunk_size)
    return max(1, math.ceil(total / 20))
