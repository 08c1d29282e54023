"""Pareto ranking and front quality: constrained non-dominated sorting, crowding, hypervolume.

Pure JAX functions of an objective matrix ``f`` of shape ``(n, m)`` (``m`` objectives, all
minimised) and a total violation ``v`` of shape ``(n,)`` (0 = feasible), so a multi-objective
colony can rank its archive under ``jit`` and ``vmap``:

* :func:`domination_matrix` - Deb's *constrained domination* (Deb et al. 2002, NSGA-II, IEEE TEC
  6(2):182-197, section VI): a feasible point dominates an infeasible one; of two infeasible
  points the smaller violation dominates; of two feasible points the usual Pareto dominance.
* :func:`nondominated_rank` - front index of every point (0 = non-dominated), by peeling fronts.
* :func:`crowding_distance` - NSGA-II's crowding distance within each front (boundaries +inf).
* :func:`rank_crowding_order` - best first: lower front, then larger crowding distance.
* :func:`hypervolume` - the exact dominated volume w.r.t. a reference point for 1, 2 or 3
  objectives (2-D: a sort and a sum; 3-D: slices along the third objective, each a 2-D volume).
* :func:`igd` - inverted generational distance of a point set to a reference front.

NaN objectives or violations count as +inf (never better than anything). Points masked out
(``mask=False``), non-finite points and points that do not strictly dominate the reference
point add no volume.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from eaco_jax.errors import ConfigError

Array = jax.Array


def _clean(f: Array, v: Array) -> tuple[Array, Array]:
    return (jnp.where(jnp.isnan(f), jnp.inf, f), jnp.where(jnp.isnan(v), jnp.inf, v))


def domination_matrix(f: Array, v: Array) -> Array:
    """``D[i, j]``: point ``i`` dominates point ``j`` under constrained domination."""
    f, v = _clean(f, v)
    feas = v <= 0
    le = jnp.all(f[:, None, :] <= f[None, :, :], axis=-1)
    lt = jnp.any(f[:, None, :] < f[None, :, :], axis=-1)
    pareto = le & lt
    fi, fj = feas[:, None], feas[None, :]
    return (fi & ~fj) | (fi & fj & pareto) | (~fi & ~fj & (v[:, None] < v[None, :]))


def nondominated_rank(f: Array, v: Array) -> Array:
    """Front index ``(n,)`` int32 of every point: 0 for those nothing dominates, 1 for those
    only front 0 dominates, and so on (constrained domination)."""
    dom = domination_matrix(f, v)
    n = f.shape[0]

    def cond(carry: tuple[Array, Array]) -> Array:
        rank, r = carry
        return jnp.any(rank < 0) & (r < n)

    def body(carry: tuple[Array, Array]) -> tuple[Array, Array]:
        rank, r = carry
        remaining = rank < 0
        dominated = jnp.any(dom & remaining[:, None], axis=0)
        return jnp.where(remaining & ~dominated, r, rank), r + 1

    rank, _ = jax.lax.while_loop(cond, body, (jnp.full((n,), -1, jnp.int32), jnp.int32(0)))
    return rank


def crowding_distance(f: Array, rank: Array) -> Array:
    """NSGA-II crowding distance ``(n,)`` of every point within its own front.

    Per objective, a front's members are sorted; the two extremes get +inf and every other
    member the gap between its neighbours divided by the front's range in that objective,
    summed over objectives. Non-finite objectives contribute 0.
    """
    n, m = f.shape
    f = jnp.where(jnp.isnan(f), jnp.inf, f)
    dist = jnp.zeros((n,), f.dtype)
    for j in range(m):
        fj = f[:, j]
        order = jnp.lexsort((fj, rank))
        rs, fs = rank[order], fj[order]
        first = rs != jnp.roll(rs, 1)
        first = first.at[0].set(True)
        last = rs != jnp.roll(rs, -1)
        last = last.at[-1].set(True)
        finite = jnp.isfinite(fj)
        big = jnp.finfo(f.dtype).max
        lo = jax.ops.segment_min(jnp.where(finite, fj, big), rank, num_segments=n)
        hi = jax.ops.segment_max(jnp.where(finite, fj, -big), rank, num_segments=n)
        span = (hi - lo)[rs]
        gap = jnp.roll(fs, -1) - jnp.roll(fs, 1)
        ok = jnp.isfinite(gap) & (span > 0) & jnp.isfinite(span)
        inner = jnp.where(ok, gap / jnp.where(ok, span, 1.0), 0.0)
        contrib = jnp.where(first | last, jnp.inf, inner)
        contrib = jnp.where(jnp.isfinite(fs), contrib, 0.0)
        dist = dist.at[order].add(contrib)
    return dist


def rank_crowding_order(f: Array, v: Array) -> tuple[Array, Array, Array]:
    """``(order, rank, crowding)``: ``order`` lists the points best first (lower front first,
    then larger crowding distance); ``rank`` and ``crowding`` are per point (unsorted)."""
    rank = nondominated_rank(f, v)
    crowd = crowding_distance(f, rank)
    return jnp.lexsort((-crowd, rank)), rank, crowd


def _valid(f: Array, ref: Array, mask: Array | None) -> Array:
    ok = jnp.all(jnp.isfinite(f), axis=-1) & jnp.all(f < ref, axis=-1)
    return ok if mask is None else ok & mask


def hypervolume_2d(f: Array, ref: Array, mask: Array | None = None) -> Array:
    """Exact area dominated by the points ``f`` ``(n, 2)`` and bounded by ``ref``.

    Any set works (dominated points add nothing): sorted by the first objective, the strip
    from one point to the next has height ``ref_2 - min f_2`` over the points so far.
    """
    ok = _valid(f, ref, mask)
    x = jnp.where(ok, f[:, 0], ref[0])
    y = jnp.where(ok, f[:, 1], ref[1])
    order = jnp.lexsort((y, x))
    xs, ys = x[order], y[order]
    ymin = jax.lax.cummin(ys)
    nxt = jnp.concatenate([xs[1:], ref[:1]])
    return jnp.sum((nxt - xs) * (ref[1] - ymin))


def hypervolume_3d(f: Array, ref: Array, mask: Array | None = None) -> Array:
    """Exact volume dominated by the points ``f`` ``(n, 3)`` and bounded by ``ref``.

    Sorted by the third objective, the slab between one point's ``f_3`` and the next one's
    is dominated over the 2-D area of the points so far: ``n`` 2-D volumes, O(n^2 log n).
    """
    n = f.shape[0]
    ok = _valid(f, ref, mask)
    z = jnp.where(ok, f[:, 2], ref[2])
    order = jnp.argsort(z)
    fs, zs, oks = f[order], z[order], ok[order]
    nxt = jnp.concatenate([zs[1:], ref[2:]])
    upto = jnp.arange(n)[None, :] <= jnp.arange(n)[:, None]
    areas = jax.vmap(lambda m: hypervolume_2d(fs[:, :2], ref[:2], m & oks))(upto)
    return jnp.sum((nxt - zs) * areas)


def hypervolume(f: Array, ref: Array, mask: Array | None = None) -> Array:
    """Exact hypervolume of ``f`` ``(n, m)`` w.r.t. ``ref`` ``(m,)`` for m = 1, 2 or 3.

    ``mask`` selects the points that count (e.g. the feasible first front).
    """
    ref = jnp.asarray(ref, f.dtype)
    m = f.shape[-1]
    if m == 1:
        ok = _valid(f, ref, mask)
        return jnp.maximum(ref[0] - jnp.min(jnp.where(ok, f[:, 0], ref[0])), 0.0)
    if m == 2:
        return hypervolume_2d(f, ref, mask)
    if m == 3:
        return hypervolume_3d(f, ref, mask)
    raise ConfigError(f"exact hypervolume is implemented for 1 to 3 objectives, got {m}")


def igd(f: Array, reference: Array, mask: Array | None = None) -> Array:
    """Inverted generational distance: the mean over ``reference`` ``(r, m)`` (points of the
    true front) of the Euclidean distance to the nearest point of ``f`` ``(n, m)`` that
    ``mask`` selects (+inf if none is selected)."""
    ok = jnp.all(jnp.isfinite(f), axis=-1)
    ok = ok if mask is None else ok & mask
    d = jnp.sqrt(jnp.sum((reference[:, None, :] - f[None, :, :]) ** 2, axis=-1))
    d = jnp.where(ok[None, :], d, jnp.inf)
    return jnp.mean(jnp.min(d, axis=1))
