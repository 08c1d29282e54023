"""The symmetric travelling salesman problem as a graph problem for the colony.

A :class:`TSP` holds the distance matrix (float32 holding exact integers for TSPLIB metrics,
exact for tour lengths below 2**24) and each city's ``k`` nearest neighbours (candidate lists
for construction and local search). Tours are ``int32`` permutations of ``0..n-1``; a tour is
closed (the last city returns to the first).

Constructors: :meth:`TSP.from_coords`, :meth:`TSP.from_distance_matrix` and
:func:`load_tsplib` (a bundled instance by name, or any ``.tsp`` file by path).
"""

from __future__ import annotations

import csv
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsplib import COORD_TYPES, coord_distances, distance_matrix, read_tsplib

DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "tsplib"
DEFAULT_NEIGHBORS = 20


def bundled_instances() -> list[str]:
    """Names of the TSPLIB instances shipped with the package."""
    return sorted(p.stem for p in DATA_DIR.glob("*.tsp"))


def bundled_optima() -> dict[str, float]:
    """Known optimal tour lengths of the bundled instances (``data/tsplib/optima.csv``)."""
    with open(DATA_DIR / "optima.csv", newline="") as fh:
        return {row["name"]: float(row["optimal_tour_length"]) for row in csv.DictReader(fh)}


def nearest_neighbors(dist: np.ndarray, k: int) -> np.ndarray:
    """``(n, min(k, n-1))`` int32: each city's nearest other cities, closest first (ties by id)."""
    d = np.array(dist, dtype=np.float64)
    n = d.shape[0]
    k = min(int(k), n - 1)
    if k < 1:
        raise ProblemError(f"neighbors must be >= 1, got {k}")
    np.fill_diagonal(d, np.inf)
    return np.argsort(d, axis=1, kind="stable")[:, :k].astype(np.int32)


def _check_matrix(d: np.ndarray) -> np.ndarray:
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
    if d.max() >= 2**24:
        raise ProblemError(
            "distances >= 2**24 cannot be held exactly in float32; rescale the matrix"
        )
    return d


@struct.dataclass
class TSP:
    """A symmetric TSP instance (a pytree: ``dist`` and ``neighbors`` are leaves).

    Attributes:
      dist: ``(n, n)`` float32 distances (exact integers for TSPLIB metrics), zero diagonal.
      neighbors: ``(n, k)`` int32, each city's ``k`` nearest other cities, closest first.
      coords: ``(n, 2)`` city coordinates when the instance has them (for plots), else None.
      name: instance name for results.
      optimum: known optimal tour length, or None.
      kind: always ``"graph"``.
    """

    dist: jax.Array
    neighbors: jax.Array
    coords: jax.Array | None = None
    name: str = struct.field(pytree_node=False, default="custom")
    optimum: float | None = struct.field(pytree_node=False, default=None)
    kind: str = struct.field(pytree_node=False, default="graph")

    @property
    def n(self) -> int:
        """Number of cities."""
        return self.dist.shape[-1]

    @jax.jit
    def evaluate(self, tours: jax.Array) -> jax.Array:
        """Closed-tour lengths ``(m,)`` float32 of int32 tours ``(m, n)``."""
        tours = jnp.asarray(tours, jnp.int32)
        nxt = jnp.roll(tours, -1, axis=-1)
        return self.dist[tours, nxt].sum(-1).astype(jnp.float32)

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
        """A TSP from a square, finite, non-negative, symmetric matrix with zero diagonal."""
        d = _check_matrix(d)
        nbr = nearest_neighbors(d, neighbors)
        return cls(
            dist=jnp.asarray(d, jnp.float32),
            neighbors=jnp.asarray(nbr),
            coords=None if coords is None else jnp.asarray(coords, jnp.float32),
            name=name,
            optimum=optimum,
        )

    @classmethod
    def from_coords(
        cls,
        coords: np.ndarray,
        name: str = "custom",
        metric: str = "EUC_2D",
        neighbors: int = DEFAULT_NEIGHBORS,
        optimum: float | None = None,
    ) -> TSP:
        """A TSP from ``(n, 2)`` coordinates and a TSPLIB metric (EUC_2D, CEIL_2D, ATT, GEO)."""
        if metric.upper() not in COORD_TYPES:
            raise ProblemError(
                f"metric {metric!r} is not supported; use one of {', '.join(COORD_TYPES)}"
            )
        return cls.from_distance_matrix(
            coord_distances(coords, metric), name=name, neighbors=neighbors, optimum=optimum,
            coords=np.asarray(coords),
        )


def load_tsplib(name_or_path: str | Path, neighbors: int = DEFAULT_NEIGHBORS) -> TSP:
    """A bundled instance by bare name (``"eil51"``) or any TSPLIB ``.tsp`` file by path.

    The optimum comes from the bundled ``optima.csv`` when the instance name matches.
    """
    text = str(name_or_path)
    bundled = DATA_DIR / f"{text}.tsp"
    if "/" not in text and "\\" not in text and not text.endswith(".tsp"):
        if not bundled.is_file():
            raise ProblemError(
                f"unknown TSPLIB instance {text!r}; bundled: {', '.join(bundled_instances())}"
                " (or pass a path to a .tsp file)"
            )
        path = bundled
    else:
        path = Path(text)
    inst = read_tsplib(path)
    name = inst.name if inst.name else path.stem
    optima = bundled_optima()
    optimum = optima.get(name, optima.get(path.stem))
    return TSP.from_distance_matrix(
        distance_matrix(inst), name=name, neighbors=neighbors, optimum=optimum,
        coords=inst.coords if inst.coords is not None and len(inst.coords) else None,
    )


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


def validate_tour(tour: np.ndarray, n: int) -> np.ndarray:
    """Check that ``tour`` is a permutation of ``0..n-1``; return it as int64, else raise."""
    t = np.asarray(tour)
    if t.shape != (n,):
        raise ProblemError(f"a tour must have shape ({n},), got {t.shape}")
    if not np.issubdtype(t.dtype, np.integer):
        if not np.all(np.isfinite(t)) or np.any(t != np.round(t)):
            raise ProblemError("a tour must hold integer city ids")
    t = t.astype(np.int64)
    if t.min() < 0 or t.max() >= n:
        raise ProblemError(f"tour has city ids outside 0..{n - 1}")
    counts = np.bincount(t, minlength=n)
    if np.any(counts != 1):
        missing = np.flatnonzero(counts == 0)[:5].tolist()
        twice = np.flatnonzero(counts > 1)[:5].tolist()
        raise ProblemError(f"tour is not a permutation: repeated {twice}, missing {missing}")
    return t


def tour_length(dist: np.ndarray, tour: np.ndarray) -> int:
    """Exact closed-tour length (int64 arithmetic) for reporting."""
    d = np.asarray(dist)
    t = validate_tour(tour, d.shape[0])
    edges = d[t, np.roll(t, -1)]
    if np.any(edges != np.round(edges)):
        raise ProblemError("tour_length needs an integer distance matrix; use TSP.evaluate")
    return int(np.asarray(np.round(edges), np.int64).sum())
