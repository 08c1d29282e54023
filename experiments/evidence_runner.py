"""Run one experiment cell: all seeds vmapped, the parameters unbatched, compiled once.

Shared by ``experiments/ablation.py`` and ``experiments/paper/``.
"""

from __future__ import annotations

import time
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

_COMPILED: dict[Any, Any] = {}


def run_cell(problem: Any, strategy: Any, params: Any, seeds: list[int], iterations: int,
             chunk: int, stop: Any = None) -> dict[str, Any]:
    """One cell: all seeds vmapped, the params *unbatched* (so a switched-off rule is skipped
    by lax.cond, as in a single run, instead of both branches running under vmap as when
    settings are vmapped), compiled once per strategy and shapes.

    Returns the final state, the history (seeds, iterations), compute seconds per iteration
    (compilation excluded) and the iterations run (``stop(state)`` ends it early)."""
    from eaco_jax.driver.minimize import iteration_step

    problem = strategy.prepare(problem)
    keys = jnp.stack([jax.random.key(s) for s in seeds])
    state = jax.vmap(lambda k: strategy.init(k, problem, params))(keys)
    params = state.params  # as the strategy cast them; strip the batch axis
    params = jax.tree.map(lambda x: x[0], params)
    state = state.replace(params=None)

    def one(prob, prm, s):
        def body(c, _):
            c, metrics = iteration_step(strategy, prob, c.replace(params=prm))
            return c.replace(params=None), metrics

        return jax.lax.scan(body, s, None, length=chunk)

    key = (strategy, chunk, _signature(problem), _signature(state), _signature(params))
    if key not in _COMPILED:
        fn = jax.jit(jax.vmap(one, in_axes=(None, None, 0)))
        _COMPILED[key] = fn.lower(problem, params, state).compile()
    fn = _COMPILED[key]
    done, seconds, hist = 0, 0.0, []
    while done < iterations:
        t0 = time.perf_counter()
        state, h = fn(problem, params, state)
        jax.block_until_ready(state)
        seconds += time.perf_counter() - t0
        hist.append({k: np.asarray(v) for k, v in h.items()})
        done += chunk
        if stop is not None and stop(state):
            break
    metrics = {k: np.concatenate([h[k] for h in hist], axis=1)[:, :iterations]
               for k in hist[0]}
    return dict(state=state.replace(params=params), history=metrics["best_cost"],
                metrics=metrics, iterations=min(done, iterations),
                seconds_per_iteration=seconds / max(done, 1))


def _signature(tree: Any) -> tuple:
    """Tree structure (static metadata included) and leaf shapes / dtypes."""
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x)))) for x in leaves)


def divisor_chunk(iterations: int, chunks: int) -> int:
    """A chunk length that divides ``iterations``, about iterations / chunks."""
    want = max(1, iterations // chunks)
    return max(c for c in range(1, want + 1) if iterations % c == 0)
