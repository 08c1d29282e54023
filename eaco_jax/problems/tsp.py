"""The symmetric travelling salesman problem as a graph problem for the colony.

A :class:`TSP` holds the distance matrix in float32 and each city's ``k`` nearest neighbours
(candidate lists for construction and local search). Tours are ``int32`` permutations of
``0..n-1``; a tour is closed (the last city returns to the first).

Exactness: TSPLIB files (and integer matrices) give integer distances (each below 2**24, so
exact in float32). Inside a compiled run a tour's length is an exact integer sum rounded once to
float32 (the colony's fitness dtype): one int32 sum when no tour can reach 2**31, else
:func:`exact_int_sum`, two int32 words (each edge split at bit 12), so no tour length overflows
below 2**19 cities; the rounding is monotone, so a shorter tour never compares longer. The
lengths :func:`~eaco_jax.minimize` reports are summed again on the host in int64.
Coordinates give real (unrounded) Euclidean distances unless a TSPLIB ``metric`` is named;
their reported lengths are float64 sums of the float32 edges. Called from the host (not
under ``jit``/``vmap``), :meth:`TSP.evaluate` checks its tours and returns float64 lengths.

Constructors: :meth:`TSP.from_coords`, :meth:`TSP.from_distance_matrix` and
:func:`load_tsplib` (a bundled instance by name, or any ``.tsp`` file by path).
"""

from __future__ import annotations

import csv
import functools
from pathlib import Path
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp_exact import (  # noqa: F401 - re-exported
    INT32_SUM_LIMIT,
    WIDE_SUM_MAX_CITIES,
    exact_int_sum,
    host_lengths,
    integer_lengths,
    validate_tour,
    words_needed,
)
from eaco_jax.problems.tsplib import COORD_TYPES, coord_distances, distance_matrix, read_tsplib

DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "tsplib"
#: instances too large for a distance matrix (sparse path only), kept apart so that code
#: walking the bundled instances with dense matrices never meets them
LARGE_DIR = DATA_DIR / "large"
DEFAULT_NEIGHBORS = 20


def bundled_instances() -> list[str]:
    """Names of the TSPLIB instances shipped with the package (dense-sized ones)."""
    return sorted(p.stem for p in DATA_DIR.glob("*.tsp"))


def large_instances() -> list[str]:
    """Names of the shipped instances past the dense path's size (``data/tsplib/large``)."""
    return sorted(p.stem for p in LARGE_DIR.glob("*.tsp"))


def _optima(folder: Path) -> dict[str, float]:
    with open(folder / "optima.csv", newline="") as fh:
        return {row["name"]: float(row["optimal_tour_length"]) for row in csv.DictReader(fh)}


def bundled_optima() -> dict[str, float]:
    """Known optimal tour lengths of the bundled instances (``data/tsplib/optima.csv``)."""
    return _optima(DATA_DIR)


def large_optima() -> dict[str, float]:
    """Known optimal tour lengths of the large instances (``data/tsplib/large/optima.csv``)."""
    return _optima(LARGE_DIR)


def bundled_path(name: str) -> Path | None:
    """The shipped ``.tsp`` file of a bare instance name, small or large; None if none."""
    for folder in (DATA_DIR, LARGE_DIR):
        if (folder / f"{name}.tsp").is_file():
            return folder / f"{name}.tsp"
    return None


def nearest_neighbors(dist: np.ndarray, k: int) -> np.ndarray:
    """``(n, min(k, n-1))`` int32: each city's nearest other cities, closest first (ties by id)."""
    d = np.array(dist, dtype=np.float64)
    n = d.shape[0]
    k = min(int(k), n - 1)
    if k < 1:
        raise ProblemError(f"neighbors must be >= 1, got {k}")
    np.fill_diagonal(d, np.inf)
    return np.argsort(d, axis=1, kind="stable")[:, :k].astype(np.int32)


def _check_matrix(d: np.ndarray, source: str = "matrix") -> tuple[np.ndarray, bool, int]:
    """The checked float64 matrix, whether every entry is an integer and the int32 words of
    its in-run tour sums (:func:`words_needed`); ``source`` is what the user gave ("matrix" or
    "coordinates"), the thing a too-large refusal tells them to rescale."""
    d = np.asarray(d)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise ProblemError(f"distance matrix must be square (n, n), got shape {d.shape}")
    if d.shape[0] < 3:
        raise ProblemError(f"a TSP needs at least 3 cities, got {d.shape[0]}")
    if not np.issubdtype(d.dtype, np.number) or np.issubdtype(d.dtype, np.complexfloating):
        raise ProblemError(f"distance matrix must be real numbers, got dtype {d.dtype}")
    d = d.astype(np.float64)
    if not np.all(np.isfinite(d)):
        raise ProblemError("distance matrix contains NaN or infinite entries")
    if np.any(d < 0):
        raise ProblemError("distance matrix contains negative entries")
    if not np.array_equal(d, d.T):
        raise ProblemError("distance matrix is not symmetric (only the symmetric TSP is supported)")
    if np.any(np.diag(d) != 0):
        raise ProblemError("distance matrix must have a zero diagonal")
    integer = bool(np.all(d == np.round(d)))
    if integer and d.max() >= 2**24:
        raise ProblemError(
            "integer distances >= 2**24 cannot be held exactly in float32; rescale the "
            f"{source}")
    longest = float(d.max(axis=1).sum())  # no tour is longer than the sum of row maxima
    if not integer and longest > 1e37:
        raise ProblemError(f"distances are too large for float32 sums; rescale the {source}")
    return d, integer, words_needed(longest, d.shape[0]) if integer else 1


@functools.partial(jax.jit, static_argnames=("integer", "words"))
def _traced_lengths(dist: jax.Array, tours: jax.Array, integer: bool,
                    words: int = 1) -> jax.Array:
    tours = jnp.asarray(tours, jnp.int32)
    edges = dist[tours, jnp.roll(tours, -1, axis=-1)]
    if integer:  # exact integer sums (the constructor chose the words every tour needs)
        return integer_lengths(edges.astype(jnp.int32), words)
    return edges.sum(-1).astype(jnp.float32)


def _is_traced(*xs: Any) -> bool:
    return any(isinstance(x, jax.core.Tracer) for x in xs)


@struct.dataclass
class TSP:
    """A symmetric TSP instance (a pytree: ``dist`` and ``neighbors`` are leaves).

    Attributes:
      dist: ``(n, n)`` float32 distances (exact integers for TSPLIB metrics), zero diagonal.
      neighbors: ``(n, k)`` int32, each city's ``k`` nearest other cities, closest first.
      coords: ``(n, 2)`` city coordinates when the instance has them (for plots), else None.
      name: instance name for results.
      optimum: known optimal tour length, or None.
      integer: every distance is an integer (TSPLIB metrics, integer matrices): tour lengths
        are then summed exactly in integers.
      sum_words: int32 words of those sums inside a run (:func:`words_needed`: 2 when a tour
        can reach 2**31).
    """

    dist: jax.Array
    neighbors: jax.Array
    coords: jax.Array | None = None
    name: str = struct.field(pytree_node=False, default="custom")
    optimum: float | None = struct.field(pytree_node=False, default=None)
    integer: bool = struct.field(pytree_node=False, default=False)
    sum_words: int = struct.field(pytree_node=False, default=1)

    kind: ClassVar[str] = "graph"

    @property
    def n(self) -> int:
        """Number of cities."""
        return self.dist.shape[-1]

    def device_view(self) -> TSP:
        """This problem without its host-only metadata (name, optimum): what compiled programs
        take, so that one program serves every instance of the same size and settings."""
        return self.replace(name="custom", optimum=None)

    def evaluate(self, tours: jax.Array) -> Any:
        """Closed-tour lengths ``(m,)`` of tours ``(m, n)``.

        Traced (inside ``jit``/``vmap``, as the driver calls it): float32, exact integer sums
        rounded once for integer distances. Called from the host with concrete tours: every
        tour is checked (a permutation of ``0..n-1``, else :class:`ProblemError`) and the
        lengths are float64, exact for integer distances.
        """
        if _is_traced(tours, self.dist):
            return _traced_lengths(self.dist, tours, self.integer, self.sum_words)
        return host_lengths(self, tours)

    def exact_length(self, tour: Any) -> float:
        """Closed length of one tour on the host (checked: a permutation of ``0..n-1``):
        an int64 sum for integer distances, else a float64 sum of the float32 edges."""
        d = np.asarray(self.dist)
        t = validate_tour(np.asarray(tour), d.shape[0])
        edges = d[t, np.roll(t, -1)]
        if self.integer:
            return float(np.asarray(edges, np.int64).sum())
        return float(np.asarray(edges, np.float64).sum())

    def host_check(self, solution: Any) -> dict[str, Any]:
        """What :func:`~eaco_jax.minimize` reports for a returned tour: its exact length
        (raises :class:`ProblemError` if it is not a permutation)."""
        return {"cost": self.exact_length(solution)}

    def gap(self, length: float) -> float | None:
        """Relative gap ``length / optimum - 1`` (None when the optimum is unknown)."""
        return None if self.optimum is None else float(length) / self.optimum - 1.0

    @classmethod
    def from_distance_matrix(
        cls,
        d: np.ndarray,
        name: str = "custom",
        neighbors: int = DEFAULT_NEIGHBORS,
        optimum: float | None = None,
        coords: np.ndarray | None = None,
    ) -> TSP:
        """A TSP from a square, finite, non-negative, symmetric matrix with zero diagonal.

        An all-integer matrix gives exact integer tour lengths; any other is held in float32.
        """
        return cls._from_checked(d, name, neighbors, optimum, coords, "matrix")

    @classmethod
    def _from_checked(cls, d: np.ndarray, name: str, neighbors: int, optimum: float | None,
                      coords: np.ndarray | None, source: str) -> TSP:
        """:meth:`from_distance_matrix` of distances computed from ``source`` ("matrix" or
        "coordinates": what a refusal tells the user to rescale)."""
        d, integer, words = _check_matrix(d, source)
        nbr = nearest_neighbors(d, neighbors)
        return cls(
            dist=jnp.asarray(d, jnp.float32),
            neighbors=jnp.asarray(nbr),
            coords=None if coords is None else jnp.asarray(coords, jnp.float32),
            name=name,
            optimum=optimum,
            integer=integer,
            sum_words=words,
        )

    @classmethod
    def from_coords(
        cls,
        coords: np.ndarray,
        name: str = "custom",
        metric: str | None = None,
        neighbors: int = DEFAULT_NEIGHBORS,
        optimum: float | None = None,
    ) -> TSP:
        """A TSP from ``(n, 2)`` coordinates.

        ``metric=None`` (default): real Euclidean distances, unrounded. A TSPLIB metric
        (``EUC_2D``, ``CEIL_2D``, ``ATT``, ``GEO``) applies that metric's integer rounding.
        """
        if metric is None:
            d = euclidean_distances(coords)
        else:
            if str(metric).upper() not in COORD_TYPES:
                raise ProblemError(
                    f"metric {metric!r} is not supported; use None (real Euclidean) or one of "
                    f"{', '.join(COORD_TYPES)}"
                )
            d = coord_distances(coords, metric)
        return cls._from_checked(d, name, neighbors, optimum, np.asarray(coords), "coordinates")


def euclidean_distances(coords: Any) -> np.ndarray:
    """``(n, n)`` float64 Euclidean distances (no rounding) between ``(n, 2)`` coordinates."""
    xy = np.asarray(coords, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ProblemError(f"coords must have shape (n, 2), got {xy.shape}")
    if not np.all(np.isfinite(xy)):
        raise ProblemError("coords contain NaN or infinite values")
    diff = xy[:, None, :] - xy[None, :, :]
    return np.sqrt((diff**2).sum(-1))


def load_tsplib(name_or_path: str | Path, neighbors: int | None = None,
                sparse: bool | None = None, sparse_from: int | None = None) -> Any:
    """A bundled instance by bare name (``"eil51"``) or any TSPLIB ``.tsp`` file by path.

    The optimum comes from the bundled ``optima.csv`` when the instance name matches.
    ``sparse``: a :class:`~eaco_jax.problems.tsp_sparse.SparseTSP` (no distance matrix,
    memory O(n k)) when True; None (default) from ``sparse_from`` (default
    ``SPARSE_MIN_CITIES``) cities on for the coordinate metrics it computes (EUC_2D, CEIL_2D,
    ATT), else a dense :class:`TSP`.
    ``neighbors``: candidate-list length (default 20 dense, 16 sparse).
    """
    text = str(name_or_path)
    bundled = bundled_path(text)
    if "/" not in text and "\\" not in text and not text.endswith(".tsp"):
        if bundled is None:
            raise ProblemError(
                f"unknown TSPLIB instance {text!r}; bundled: "
                f"{', '.join(bundled_instances() + large_instances())}"
                " (or pass a path to a .tsp file)"
            )
        path = bundled
    else:
        path = Path(text)
    inst = read_tsplib(path)
    name = inst.name if inst.name else path.stem
    optima = {**large_optima(), **bundled_optima()}
    optimum = optima.get(name, optima.get(path.stem))
    from eaco_jax.problems import tsp_sparse
    from eaco_jax.problems.tsplib import check_dimension

    can_sparse = inst.edge_weight_type in tsp_sparse.SPARSE_METRICS
    if sparse is None:
        least = tsp_sparse.SPARSE_MIN_CITIES if sparse_from is None else int(sparse_from)
        sparse = can_sparse and inst.dimension >= least
    if sparse:
        if not can_sparse:
            raise ProblemError(
                f"{path}: EDGE_WEIGHT_TYPE {inst.edge_weight_type} has no sparse path; use "
                f"one of {', '.join(tsp_sparse.SPARSE_METRICS[:3])} or the dense path")
        return tsp_sparse.SparseTSP.from_coords(
            inst.coords, name=name, metric=inst.edge_weight_type, optimum=optimum,
            neighbors=tsp_sparse.SPARSE_NEIGHBORS if neighbors is None else neighbors)
    check_dimension(inst.dimension, str(path))
    neighbors = DEFAULT_NEIGHBORS if neighbors is None else neighbors
    return TSP._from_checked(
        distance_matrix(inst), name, neighbors, optimum,
        inst.coords if inst.coords is not None and len(inst.coords) else None,
        "coordinates" if inst.edge_weight_type in COORD_TYPES else "matrix")


@jax.jit
def _nn_tour(dist: jax.Array, start: jax.Array) -> jax.Array:
    n = dist.shape[0]

    def step(i, carry):
        tour, visited = carry
        cur = tour[i - 1]
        nxt = jnp.argmin(jnp.where(visited, jnp.inf, dist[cur])).astype(jnp.int32)
        return tour.at[i].set(nxt), visited.at[nxt].set(True)

    tour = jnp.zeros(n, jnp.int32).at[0].set(start)
    visited = jnp.zeros(n, bool).at[start].set(True)
    tour, _ = jax.lax.fori_loop(1, n, step, (tour, visited))
    return tour


def nearest_neighbour_tour(dist: np.ndarray, start: int = 0) -> np.ndarray:
    """Greedy nearest-neighbour tour from ``start`` (ties to the lowest city id), int32 (n,)."""
    d = np.asarray(dist)
    n = d.shape[0]
    if d.ndim != 2 or d.shape[1] != n:
        raise ProblemError(f"distance matrix must be square (n, n), got shape {d.shape}")
    if not 0 <= int(start) < n:
        raise ProblemError(f"start city {start} outside 0..{n - 1}")
    return np.asarray(_nn_tour(jnp.asarray(d, jnp.float32), jnp.int32(start)))


def tour_length(dist: np.ndarray, tour: np.ndarray) -> int:
    """Exact closed-tour length (int64 arithmetic) for reporting."""
    d = np.asarray(dist)
    t = validate_tour(tour, d.shape[0])
    edges = d[t, np.roll(t, -1)]
    if np.any(edges != np.round(edges)):
        raise ProblemError("tour_length needs an integer distance matrix; use TSP.evaluate")
    return int(np.asarray(np.round(edges), np.int64).sum())
