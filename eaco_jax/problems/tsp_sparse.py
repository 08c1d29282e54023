"""The symmetric TSP without a distance matrix: memory O(n k) for n cities and k candidates.

A :class:`SparseTSP` keeps the coordinates and each city's ``k`` nearest cities (from a k-d
tree, ``scipy.spatial.cKDTree``; no n x n array is ever built) and computes any distance from
the coordinates when it is read (:class:`CoordDistances`, indexed like a matrix:
``dist[a, b]``). The graph colony (``strategies/graph_eaco.py``) then holds its pheromone and
choice information on the candidate edges only.

Exactness: for integer coordinates the TSPLIB metrics ``EUC_2D``, ``CEIL_2D`` and ``ATT`` are
computed exactly in 32-bit arithmetic: a float32 square root gives a guess within a few units,
and the exact integer comparison of the squared length with the guess's bounds corrects it
(int32 products wrap modulo 2**32, but the differences compared are small, so they are exact).
The distances are those of :func:`~eaco_jax.problems.tsplib.coord_distances` (a test compares
them). Non-integer coordinates are computed in float32 (an edge may then differ by one unit
from the float64 TSPLIB value where its length lies within a float32 rounding of a rounding
boundary); the lengths :func:`~eaco_jax.minimize` reports are always recomputed on the host in
float64 / int64 (:meth:`SparseTSP.exact_length`). Tour lengths inside a run are exact integer
sums as on the dense path (:func:`~eaco_jax.problems.tsp_exact.integer_lengths`).
"""

from __future__ import annotations

import functools
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp_exact import host_lengths, integer_lengths, validate_tour, words_needed
from eaco_jax.problems.tsplib import pair_distances

#: metrics the sparse path computes from coordinates (GEO's trigonometry is left to the dense
#: path, whose instances are small)
SPARSE_METRICS = ("EUC_2D", "CEIL_2D", "ATT", "EUCLIDEAN")
#: candidate-list length of the sparse path when none is given (Focused ACO's range 10-16)
SPARSE_NEIGHBORS = 16
#: from this many cities ``load_tsplib`` (and ``eaco tsp``) take the sparse path by default:
#: the dense path's host matrices then pass ~1 GiB (16 n^2 bytes); a round size, not a measured
#: crossing of the two paths (docs/tsp_large.md)
SPARSE_MIN_CITIES = 8000


def _isqrt_fix(s: jax.Array, t: jax.Array, scale: int, ceil: bool) -> jax.Array:
    """Correct the guess ``t`` of round-half-up (``ceil=False``) or ceil (``ceil=True``) of
    ``sqrt(s / scale)`` for int32 ``s`` given modulo 2**32 (wrapping products), exact while
    the guess is within a few units. Compares ``scale t^2`` with ``s`` as int32 differences."""
    for _ in range(3):
        if ceil:  # ceil(sqrt(s/scale)) = t  iff  scale (t-1)^2 < s <= scale t^2
            up = (s - scale * t * t) > 0
            down = (s - scale * (t - 1) * (t - 1)) <= 0
        else:  # nint(sqrt(s)) = t  iff  t^2 - t + 1 <= s <= t^2 + t   (scale is 1)
            r = s - t * t
            up, down = r > t, r < 1 - t
        t = t + up.astype(jnp.int32) - (down & (t > 0)).astype(jnp.int32)
    return t


def coord_distance(a: jax.Array, b: jax.Array, metric: str, exact: bool) -> jax.Array:
    """float32 distances between coordinates ``a`` and ``b`` (..., 2) under ``metric``
    (:data:`SPARSE_METRICS`; "EUCLIDEAN" unrounded). ``exact``: int32 coordinates, TSPLIB
    rounding computed exactly (see the module docstring)."""
    if exact and metric != "EUCLIDEAN":
        dx = a[..., 0] - b[..., 0]
        dy = a[..., 1] - b[..., 1]
        fx, fy = dx.astype(jnp.float32), dy.astype(jnp.float32)
        s = dx * dx + dy * dy  # int32, modulo 2**32
        sf = fx * fx + fy * fy
        if metric == "EUC_2D":
            t = jnp.floor(jnp.sqrt(sf) + 0.5).astype(jnp.int32)
            t = _isqrt_fix(s, t, 1, ceil=False)
        elif metric == "CEIL_2D":
            t = _isqrt_fix(s, jnp.ceil(jnp.sqrt(sf)).astype(jnp.int32), 1, ceil=True)
        else:  # ATT: t = nint(r), t + 1 if t < r: ceil(sqrt(s / 10))
            t = _isqrt_fix(s, jnp.ceil(jnp.sqrt(sf / 10.0)).astype(jnp.int32), 10, ceil=True)
        return t.astype(jnp.float32)
    a = a.astype(jnp.float32)
    b = b.astype(jnp.float32)
    dx = a[..., 0] - b[..., 0]
    dy = a[..., 1] - b[..., 1]
    sq = dx * dx + dy * dy
    if metric == "EUCLIDEAN":
        return jnp.sqrt(sq)
    if metric == "EUC_2D":
        return jnp.floor(jnp.sqrt(sq) + 0.5)
    if metric == "CEIL_2D":
        return jnp.ceil(jnp.sqrt(sq))
    r = jnp.sqrt(sq / 10.0)
    t = jnp.floor(r + 0.5)
    return jnp.where(t < r, t + 1.0, t)


class HostArray:
    """A host numpy array as a static pytree field: compared and hashed by its content's
    digest (jit caches and exported programs key on static fields)."""

    __slots__ = ("value", "digest")

    def __init__(self, value: np.ndarray) -> None:
        import hashlib

        self.value = np.ascontiguousarray(value)
        self.digest = hashlib.sha256(self.value.tobytes()).hexdigest()[:16]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, HostArray) and other.digest == self.digest

    def __hash__(self) -> int:
        return hash(self.digest)

    def __repr__(self) -> str:
        return f"HostArray({self.value.shape}, {self.digest})"


@struct.dataclass
class CoordDistances:
    """A distance 'matrix' computed from coordinates when read: ``d[a, b]`` for index arrays
    ``a`` and ``b`` (broadcast) gives float32 distances, as indexing an (n, n) array would."""

    coords: jax.Array
    metric: str = struct.field(pytree_node=False, default="EUC_2D")
    exact: bool = struct.field(pytree_node=False, default=False)

    #: read by the local searches (``ops.local_search.as_distances``): no matrix to convert
    on_the_fly: ClassVar[bool] = True

    @property
    def shape(self) -> tuple[int, int]:
        n = self.coords.shape[0]
        return (n, n)

    def __getitem__(self, index: tuple[Any, Any]) -> jax.Array:
        a, b = index
        return coord_distance(self.coords[a], self.coords[b], self.metric, self.exact)

    def __jax_array__(self) -> jax.Array:
        raise ProblemError(
            "this TSP takes the sparse path (no distance matrix); use the graph colony "
            "(GraphEACO, eaco tsp) or load it with sparse=False")


def candidate_lists(xy: np.ndarray, k: int, metric: str) -> np.ndarray:
    """``(n, k)`` int32 nearest other cities by ``metric``'s distance, ties by id (the order
    of :func:`~eaco_jax.problems.tsp.nearest_neighbors` on the dense matrix), from a k-d tree:
    O(n k log n) time and O(n k) memory."""
    from scipy.spatial import cKDTree

    n = xy.shape[0]
    k = min(int(k), n - 1)
    if k < 1:
        raise ProblemError(f"neighbors must be >= 1, got {k}")
    # a few more than k by real distance, re-ranked by the rounded metric (ties by id), so
    # the lists are those of the dense matrix unless more than `extra` tie at the boundary
    q = min(n, k + 1 + 8)
    _, idx = cKDTree(xy).query(xy, k=q)
    idx = np.asarray(idx, np.int64).reshape(n, q)
    d = pair_distances(xy[:, None, :], xy[idx], "EUC_2D" if metric == "EUCLIDEAN" else metric,
                       rounded=metric != "EUCLIDEAN")
    d = np.where(idx == np.arange(n)[:, None], np.inf, d)
    order = np.lexsort((idx, d), axis=-1)  # by distance, then id
    return np.take_along_axis(idx, order, axis=1)[:, :k].astype(np.int32)


@functools.partial(jax.jit, static_argnames=("metric", "exact", "words"))
def _traced_lengths(coords: jax.Array, tours: jax.Array, metric: str, exact: bool,
                    words: int) -> jax.Array:
    tours = jnp.asarray(tours, jnp.int32)
    d = CoordDistances(coords, metric, exact)[tours, jnp.roll(tours, -1, axis=-1)]
    if metric == "EUCLIDEAN":
        return d.sum(-1).astype(jnp.float32)
    return integer_lengths(d.astype(jnp.int32), words)


@struct.dataclass
class SparseTSP:
    """A symmetric TSP from coordinates without a distance matrix (a pytree).

    Attributes:
      coords: ``(n, 2)`` coordinates: int32 when ``exact``, else float32.
      neighbors: ``(n, k)`` int32 candidate lists, nearest first (ties by id).
      host_coords: the float64 coordinates as read (:class:`HostArray`, host only: exact
        lengths and plots).
      metric: a TSPLIB metric of :data:`SPARSE_METRICS` ("EUCLIDEAN": unrounded).
      exact: integer coordinates, distances computed exactly (module docstring).
      integer: distances are integers (every TSPLIB metric).
      sum_words: int32 words of in-run tour sums
        (:func:`~eaco_jax.problems.tsp_exact.words_needed`).
    """

    coords: jax.Array
    neighbors: jax.Array
    host_coords: HostArray | None = struct.field(pytree_node=False, default=None)
    name: str = struct.field(pytree_node=False, default="custom")
    optimum: float | None = struct.field(pytree_node=False, default=None)
    metric: str = struct.field(pytree_node=False, default="EUC_2D")
    exact: bool = struct.field(pytree_node=False, default=False)
    integer: bool = struct.field(pytree_node=False, default=True)
    sum_words: int = struct.field(pytree_node=False, default=1)

    kind: ClassVar[str] = "graph"
    #: the graph colony keeps pheromone on candidate edges only for this problem
    sparse: ClassVar[bool] = True

    @property
    def n(self) -> int:
        """Number of cities."""
        return self.coords.shape[0]

    @property
    def dist(self) -> CoordDistances:
        """Distances computed from the coordinates when read (``dist[a, b]``)."""
        return CoordDistances(self.coords, self.metric, self.exact)

    def device_view(self) -> SparseTSP:
        """This problem without its host-only metadata (coordinates as read, name, optimum):
        what compiled programs take, so that one program serves every instance of the same
        size and settings (the exact host length needs ``host_coords``: keep the original)."""
        return self.replace(host_coords=None, name="custom", optimum=None)

    def evaluate(self, tours: jax.Array) -> Any:
        """Closed-tour lengths ``(m,)``: traced, float32 (exact integer sums rounded once);
        from the host, checked tours and float64 lengths (:meth:`exact_length`)."""
        if isinstance(tours, jax.core.Tracer) or isinstance(self.coords, jax.core.Tracer):
            return _traced_lengths(self.coords, tours, self.metric, self.exact,
                                   self.sum_words)
        return host_lengths(self, tours)

    def exact_length(self, tour: Any) -> float:
        """Closed length of one tour on the host, checked (a permutation of ``0..n-1``):
        TSPLIB distances in float64, summed in int64 (float64 for "EUCLIDEAN")."""
        t = validate_tour(np.asarray(tour), self.n)
        xy = np.asarray(self.host_coords.value, np.float64)
        d = pair_distances(xy[t], xy[np.roll(t, -1)],
                           "EUC_2D" if self.metric == "EUCLIDEAN" else self.metric,
                           rounded=self.metric != "EUCLIDEAN")
        if self.metric == "EUCLIDEAN":
            return float(d.sum())
        return float(np.asarray(d, np.int64).sum())

    def host_check(self, solution: Any) -> dict[str, Any]:
        """What :func:`~eaco_jax.minimize` reports for a returned tour: its exact length."""
        return {"cost": self.exact_length(solution)}

    def gap(self, length: float) -> float | None:
        """Relative gap ``length / optimum - 1`` (None when the optimum is unknown)."""
        return None if self.optimum is None else float(length) / self.optimum - 1.0

    @classmethod
    def from_coords(cls, coords: Any, name: str = "custom", metric: str | None = "EUC_2D",
                    neighbors: int = SPARSE_NEIGHBORS,
                    optimum: float | None = None) -> SparseTSP:
        """A sparse TSP from ``(n, 2)`` coordinates under a TSPLIB ``metric`` (``EUC_2D``,
        ``CEIL_2D``, ``ATT``) or ``None`` (real Euclidean, unrounded)."""
        metric = "EUCLIDEAN" if metric is None else str(metric).upper()
        if metric not in SPARSE_METRICS:
            raise ProblemError(
                f"metric {metric!r} has no sparse path; use one of EUC_2D, CEIL_2D, ATT, None "
                "(or sparse=False for the dense path)")
        xy = np.asarray(coords, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ProblemError(f"coords must have shape (n, 2), got {xy.shape}")
        n = xy.shape[0]
        if n < 3:
            raise ProblemError(f"a TSP needs at least 3 cities, got {n}")
        if not np.all(np.isfinite(xy)):
            raise ProblemError("coords contain NaN or infinite values")
        span = float(np.max(xy.max(0) - xy.min(0)))
        longest_edge = span * np.sqrt(2.0) + 1.0
        integer = metric != "EUCLIDEAN"
        if integer and longest_edge >= 2**24:
            raise ProblemError(
                f"coordinates spanning {span:.0f} give distances >= 2**24, beyond exact "
                "float32 integers; rescale the coordinates")
        exact = integer and bool(np.all(xy == np.round(xy))) and span < 2**30
        words = words_needed(n * longest_edge, n) if integer else 1
        base = xy - np.floor(xy.min(0))  # shifted: int32 coordinates, float32 precision
        nbr = candidate_lists(xy, neighbors, metric)
        return cls(
            coords=jnp.asarray(base, jnp.int32 if exact else jnp.float32),
            neighbors=jnp.asarray(nbr), host_coords=HostArray(xy), name=name, optimum=optimum,
            metric=metric, exact=exact, integer=integer, sum_words=words)


def is_sparse(problem: Any) -> bool:
    """Whether ``problem`` is a graph problem without a distance matrix (candidate edges)."""
    return bool(getattr(problem, "sparse", False))
