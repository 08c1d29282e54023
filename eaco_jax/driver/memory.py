"""Memory checks: a colony whose state, or one iteration's working set, would not fit is refused
before anything is allocated; a device out of memory in a chunk is one line."""

from __future__ import annotations

import warnings
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from eaco_jax.errors import ConfigError
from eaco_jax.strategies.base import Strategy


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


def tree_nbytes(tree: Any) -> int:
    """Bytes of the arrays (or abstract shapes) in ``tree``, PRNG keys not counted."""
    return sum(int(np.prod(a.shape)) * np.dtype(a.dtype).itemsize for a in jax.tree.leaves(tree)
               if hasattr(a, "dtype") and not jnp.issubdtype(a.dtype, jax.dtypes.prng_key))


def state_row_bytes(strategy: Strategy, problem: Any, params: Any) -> int:
    """Bytes of one row of the colony state (abstract: nothing allocated)."""
    return tree_nbytes(jax.eval_shape(lambda k: strategy.init(k, problem, params),
                                      jax.random.key(0)))


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
            # a focused search (ls_focus_width) evaluates the moves of at most that many
            # cities a step: its per-candidate arrays are focus x candidates, not n x candidates
            focus = min(n, int(getattr(strategy, "ls_focus_width", None) or n))
            work += searched * (n * LS_CITY_BYTES + focus * LS_CANDIDATE_BYTES * scanned)
            what += f" and searching {searched} of them"
        return work, what
    if getattr(problem, "kind", None) == "continuous" and getattr(strategy, "refine_ants", 0):
        dim = int(getattr(problem, "dim", 0))
        itemsize = np.dtype(getattr(problem, "dtype", np.float32)).itemsize
        return (HESSIAN_MATRICES * itemsize * dim * dim,
                f"refinement's {dim} x {dim} Hessians")
    return 0, ""


def check_state_memory(strategy: Strategy, problem: Any, rows: int, params: Any,
                       state_bytes: int | None = None) -> None:
    """Refuse a colony whose state, or state plus one iteration's working set
    (:func:`working_set_bytes`), would not fit in memory (abstract: nothing allocated); warn in
    one line when one iteration needs more than :data:`WARN_WORKING_SET`. ``state_bytes``:
    the whole state's size where a compiled initialiser already tells it (None: traced here,
    :func:`state_row_bytes` times ``rows``)."""
    one = params[0] if isinstance(params, list | tuple) else params
    need = state_row_bytes(strategy, problem, one) * rows if state_bytes is None \
        else int(state_bytes)
    limit = _memory_limit()
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


def out_of_memory(err: Exception, strategy: Strategy, problem: Any,
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
