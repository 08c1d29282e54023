"""Operators on start-to-goal node sequences (path colony and path GA).

A path is a fixed-length ``(n,)`` int32 sequence of graph nodes: ``START`` first, the goal once
reached and then repeated. ``cost`` below is an ``(n, n)`` edge-cost matrix with +inf where the
edge is blocked (a problem's ``step_cost``: lengths or walking times).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array

#: node numbering of every path problem: the start is node 0, the goal node 1
START, GOAL = 0, 1


def goal_position(path: Array) -> Array:
    """Index of the path's first arrival at the goal (``n - 1`` if it never arrives)."""
    hit = path == GOAL
    return jnp.where(jnp.any(hit), jnp.argmax(hit), path.shape[0] - 1)


def common_node_crossover(key: Array, a: Array, b: Array) -> Array:
    """Follow ``a`` up to a random node that ``b`` also visits, then ``b`` to the goal.

    Nodes are compared up to each parent's first arrival at the goal; with no common inner node
    the child is ``a``.
    """
    n = a.shape[0]
    idx = jnp.arange(n)
    in_b = jnp.any(a[:, None] == b[None, :], axis=1)
    inner = (a != START) & (a != GOAL) & in_b
    pick = jax.random.categorical(key, jnp.where(inner, 0.0, -jnp.inf))
    any_common = jnp.any(inner)
    pos_a = jnp.where(any_common, pick, n)
    pos_b = jnp.argmax(b == a[jnp.minimum(pick, n - 1)])
    src = idx - pos_a + pos_b
    child = jnp.where(idx < pos_a, a, jnp.where(src < n, b[jnp.clip(src, 0, n - 1)], GOAL))
    return child.astype(jnp.int32)


def shortcut(path: Array, cost: Array) -> Array:
    """String pulling: from each kept node jump to the furthest later node reachable by one edge
    no dearer than the path's own edges between them.

    With lengths as ``cost`` (the triangle inequality) every visible node qualifies, and the path
    never lengthens. With walking times a direct edge may be dearer (up a ramp) and is then
    skipped; turning is not part of the comparison. A dead path (blocked edge, no goal) is
    returned as is.
    """
    n = path.shape[0]
    idx = jnp.arange(n)
    steps = jnp.where(path[:-1] == path[1:], 0.0, cost[path[:-1], path[1:]])
    cum = jnp.concatenate([jnp.zeros((1,), cost.dtype), jnp.cumsum(steps)])

    def step(pos, _):
        node = path[pos]
        direct = cost[node, path]
        ok = jnp.isfinite(direct) & (idx > pos) & (direct <= (cum - cum[pos]) * (1 + 1e-6))
        nxt = jnp.where(path[pos] == GOAL, pos, jnp.max(jnp.where(ok, idx, pos + 1)))
        nxt = jnp.minimum(nxt, n - 1)
        return nxt, path[nxt]

    _, rest = jax.lax.scan(step, jnp.int32(0), None, length=n - 1)
    out = jnp.concatenate([path[:1], rest])
    valid = (path[-1] == GOAL) & jnp.all(jnp.isfinite(steps))
    return jnp.where(valid, out, path).astype(jnp.int32)


def path_diversity(paths: Array, n: int) -> Array:
    """Mean pairwise Jaccard distance of the paths' undirected edge sets, in [0, 1]."""
    a, b = paths[:, :-1], paths[:, 1:]
    m = paths.shape[0]
    e = jnp.zeros((m, n, n), jnp.float32).at[jnp.arange(m)[:, None], a, b].max(
        jnp.where(a != b, 1.0, 0.0))
    e = jnp.maximum(e, jnp.swapaxes(e, 1, 2)).reshape(m, -1)
    inter = e @ e.T
    sizes = e.sum(axis=1)
    union = sizes[:, None] + sizes[None, :] - inter
    dist = jnp.where(union > 0, 1.0 - inter / jnp.maximum(union, 1.0), 0.0)
    return (dist.sum() / jnp.maximum(m * (m - 1), 1)).astype(jnp.float32)


def random_walk(key: Array, cost: Array) -> Array:
    """A random simple path: from START take the goal when it is one edge away, else a uniformly
    random unvisited neighbour; a walk that gets stuck stays put (and never reaches the goal)."""
    n = cost.shape[0]
    free = jnp.isfinite(cost)

    def step(carry, k):
        cur, visited = carry
        cand = free[cur] & ~visited
        pick = jax.random.categorical(k, jnp.where(cand, 0.0, -jnp.inf))
        nxt = jnp.where(cur == GOAL, GOAL,
                        jnp.where(cand[GOAL], GOAL, jnp.where(jnp.any(cand), pick, cur)))
        return (nxt, visited.at[nxt].set(True)), nxt

    visited = jnp.zeros((n,), bool).at[START].set(True)
    _, seq = jax.lax.scan(step, (jnp.int32(START), visited), jax.random.split(key, n - 1))
    return jnp.concatenate([jnp.array([START]), seq]).astype(jnp.int32)


def mutate(key: Array, path: Array, cost: Array) -> Array:
    """One random edit of a path's inner waypoints, kept only where the new edges exist:
    replace a node by one joined to both its neighbours, delete a node whose neighbours are
    joined, or insert a node between two consecutive ones. Otherwise the path is unchanged."""
    n = path.shape[0]
    idx = jnp.arange(n)
    free = jnp.isfinite(cost)
    g = goal_position(path)
    k_op, k_pos, k_node = jax.random.split(key, 3)
    op = jax.random.randint(k_op, (), 0, 3)
    # replace / delete act on an inner node k in [1, g - 1]; insert goes after k in [0, g - 1]
    k = jnp.where(op == 2, jax.random.randint(k_pos, (), 0, jnp.maximum(g, 1)),
                  jax.random.randint(k_pos, (), 1, jnp.maximum(g, 2)))
    prev, here = path[jnp.maximum(k - 1, 0)], path[k]
    nxt = path[jnp.minimum(k + 1, n - 1)]
    used = jnp.zeros((n,), bool).at[path].set(True)
    left, right = jnp.where(op == 2, here, prev), jnp.where(op == 2, nxt, nxt)
    cand = free[left] & free[:, right] & ~used
    c = jax.random.categorical(k_node, jnp.where(cand, 0.0, -jnp.inf))
    replaced = path.at[k].set(c)
    deleted = jnp.where(idx < k, path, path[jnp.minimum(idx + 1, n - 1)])
    inserted = jnp.where(idx <= k, path, jnp.where(idx == k + 1, c, path[jnp.maximum(idx - 1, 0)]))
    inner = (g >= 2) & (path[-1] == GOAL)
    out = jnp.select(
        [(op == 0) & inner & jnp.any(cand),
         (op == 1) & inner & free[prev, nxt],
         (op == 2) & (path[-1] == GOAL) & (g < n - 1) & jnp.any(cand)],
        [replaced, deleted, inserted], path)
    return out.astype(jnp.int32)
