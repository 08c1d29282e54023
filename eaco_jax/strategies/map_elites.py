"""MAP-Elites: a quality-diversity archive over a grid of descriptor cells (Mouret & Clune
2015, "Illuminating search spaces by mapping elites", arXiv:1504.04909).

The archive is a grid over the problem's descriptor box (``grid`` cells per descriptor;
descriptors outside the box go to the border cell, as QDax's nearest-centroid rule and
pyribs' grid archive do): per cell the best cost found (``+inf``: empty), its solution and its
descriptor. Each iteration:

* **ask**: every ant takes a parent drawn uniformly from the filled cells and varies it.
  ``variation="isoline"`` is the baseline, Vassiliades & Mouret's Iso+LineDD (GECCO 2018):
  ``x = x_p + iso_sigma (hi - lo) N(0, I) + line_sigma N(0, 1) (x_q - x_p)`` with a second
  uniform parent ``q``. ``variation="eaco"`` is the colony's continuous sampling (ACO_R's
  pheromone kernel, as :mod:`~eaco_jax.strategies.continuous_eaco`) made local: the Gaussian
  around the parent has, per coordinate, the width ``rho * mean |x_e - x_p|`` over the elites
  ``e`` of the filled cells within ``radius`` grid cells of the parent's (the pheromone of its
  neighbourhood: wide where neighbouring elites differ, narrow where they agree), and
  ``iso_sigma (hi - lo)`` where the parent has no filled neighbour; the line term is the same.
  With ``p_coordinate < 1`` each ant redraws only some coordinates (at least one), as
  :class:`~eaco_jax.strategies.mo_eaco.MOEACO` does. While the archive is empty, ants are
  drawn uniformly in the box. Bounds are exact (clipped).
* **tell**: every ant goes to its descriptor's cell; per cell the best ant of the batch (the
  first on ties) replaces the elite if its cost is strictly lower. Non-finite costs or
  descriptors are never inserted.

Metrics: ``coverage`` (fraction of cells filled), ``qd_score`` (``sum over filled cells of
qd_offset - cost``, QDax's definition with fitness ``-cost``), ``max_fitness`` (``-`` the
lowest cost in the archive) and ``inserted`` (cells improved this iteration). ``best_cost``
is minus the largest QD score seen (everything is minimised; ``problem.shown_best`` shows the
score), ``best_solution`` the archive's lowest-cost elite, and ``stagnation`` counts
iterations without a larger QD score. Evaluation accounting: one evaluation per ant; ``init``
evaluates nothing (the first colony is uniform in the box).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from eaco_jax.errors import ConfigError
from eaco_jax.problems.qd import QDEvaluation, check_qd_problem
from eaco_jax.strategies.base import (
    NONNEG,
    POSITIVE,
    UNIT,
    Range,
    State,
    Strategy,
    as_params,
    base_fields,
)

Array = jax.Array
VARIATIONS = ("isoline", "eaco")


@struct.dataclass
class MAPElitesParams:
    """Traced hyper-parameters of MAP-Elites (vmappable). ``rho`` chosen by measurement on the
    Rastrigin-proj toy's selection seeds (claim ``qd-toy-rho-selection``)."""

    iso_sigma: Array = 0.01  # isotropic Gaussian width, as a fraction of the box width
    line_sigma: Array = 0.1  # width of the step along the line to a second parent
    rho: Array = 1.0  # eaco: kernel width = rho * mean |x_e - x_p| over neighbouring elites
    p_coordinate: Array = 1.0  # eaco: probability each coordinate is redrawn (at least one)

    RANGES: ClassVar[dict[str, Range]] = {
        "iso_sigma": NONNEG, "line_sigma": NONNEG, "rho": POSITIVE, "p_coordinate": UNIT,
    }


@struct.dataclass
class MAPElitesState(State):
    archive_x: Array  # (C, n) elite of each cell (a uniform point where empty)
    archive_cost: Array  # (C,) its cost; +inf: the cell is empty
    archive_desc: Array  # (C, d) its measured descriptor
    qd_score: Array  # of the current archive


@dataclasses.dataclass(frozen=True)
class MAPElites(Strategy):
    """Grid MAP-Elites over a QD problem's descriptor box (see the module docstring)."""

    num_ants: int = 32
    grid: tuple[int, ...] = (10, 10)
    variation: str = "isoline"
    radius: int = 1  # eaco: neighbourhood of a cell, in grid cells (Chebyshev distance)
    problem_kind: ClassVar[str] = "qd"
    migrates: ClassVar[bool] = False  # a migrant needs its problem to find its cell

    def __post_init__(self) -> None:
        if self.num_ants < 1:
            raise ConfigError("MAPElites needs num_ants >= 1")
        grid = tuple(self.grid) if isinstance(self.grid, list | tuple) else ()
        if not grid or not all(isinstance(g, int | np.integer) and g >= 1 for g in grid):
            raise ConfigError(f"MAPElites grid must be a tuple of cell counts >= 1 per "
                              f"descriptor, e.g. (10, 10), got {self.grid!r}")
        object.__setattr__(self, "grid", tuple(int(g) for g in grid))
        if self.variation not in VARIATIONS:
            raise ConfigError(f"MAPElites variation must be one of {', '.join(VARIATIONS)}, "
                              f"got {self.variation!r}")
        if not isinstance(self.radius, int) or self.radius < 1:
            raise ConfigError(f"MAPElites radius must be an int >= 1, got {self.radius!r}")

    @property
    def num_cells(self) -> int:
        return math.prod(self.grid)

    def default_params(self, problem: Any = None) -> MAPElitesParams:
        return MAPElitesParams()

    def inactive_params(self, params: MAPElitesParams) -> dict[str, str]:
        """Fields without effect under these switches -> the switch that makes them act."""
        if self.variation == "isoline":
            return dict.fromkeys(("rho", "p_coordinate"), "variation='eaco'")
        return {}

    def prepare(self, problem: Any) -> Any:
        """Check that ``problem`` is a QD problem whose descriptors match ``grid``."""
        check_qd_problem(problem, "MAPElites")
        d = int(np.shape(problem.descriptor_lower)[-1])
        if d != len(self.grid):
            raise ConfigError(f"MAPElites grid {self.grid} has {len(self.grid)} axes but "
                              f"{problem.name!r} has {d} descriptors: give one cell count per "
                              "descriptor")
        return problem

    def check_fitness(self, fitness: Any) -> None:
        """One ConfigError line, before tracing, unless ``fitness`` is a QDEvaluation."""
        if not isinstance(fitness, QDEvaluation) or np.ndim(fitness.descriptors) != 2:
            raise ConfigError(
                "MAPElites.tell needs fitness as QDEvaluation(f, descriptors) with descriptors "
                "of shape (ants, d) (what a QD problem's evaluate returns), got "
                f"{type(fitness).__name__}")

    def scalar_cost(self, fitness: QDEvaluation) -> Array:
        return fitness.f.astype(jnp.float32)

    # ----------------------------------------------------------------- cells
    def cell_index(self, descriptors: Array, problem: Any) -> Array:
        """Flat cell index ``(m,)`` of descriptors ``(m, d)`` (row-major over ``grid``; outside
        the descriptor box: the border cell)."""
        lo = problem.descriptor_lower.astype(descriptors.dtype)
        hi = problem.descriptor_upper.astype(descriptors.dtype)
        g = jnp.asarray(self.grid, jnp.int32)
        u = (descriptors - lo) / (hi - lo)
        u = jnp.where(jnp.isfinite(u), u, 0.0)
        idx = jnp.clip(jnp.floor(u * g).astype(jnp.int32), 0, g - 1)
        strides = np.cumprod((self.grid[1:] + (1,))[::-1])[::-1].astype(np.int32)
        return idx @ jnp.asarray(strides)

    def cell_coords(self) -> np.ndarray:
        """``(C, d)`` grid coordinates of every cell, in flat-index order."""
        return np.stack(np.unravel_index(np.arange(self.num_cells), self.grid), -1).astype(
            np.int32)

    def cell_centres(self, problem: Any) -> np.ndarray:
        """``(C, d)`` descriptor at the centre of every cell (host array)."""
        lo = np.asarray(problem.descriptor_lower, np.float64)
        hi = np.asarray(problem.descriptor_upper, np.float64)
        return lo + (self.cell_coords() + 0.5) / np.asarray(self.grid) * (hi - lo)

    # ----------------------------------------------------------------- init
    def _init(self, key: Array, problem: Any, params: MAPElitesParams) -> MAPElitesState:
        """An empty archive (costs +inf; placeholder elites uniform in the box)."""
        dtype = problem.dtype
        params = as_params(params, dtype)
        k_arch, k_run = jax.random.split(key)
        lo, hi = problem.lower, problem.upper
        c = self.num_cells
        x = lo + (hi - lo) * jax.random.uniform(k_arch, (c, problem.dim), dtype)
        d = len(self.grid)
        return MAPElitesState(
            **base_fields(k_run, params, x[0]),
            archive_x=x,
            archive_cost=jnp.full((c,), jnp.inf, dtype),
            archive_desc=jnp.full((c, d), jnp.nan, dtype),
            qd_score=jnp.zeros((), dtype),
        )

    # ----------------------------------------------------------------- ask
    def _ask(self, key: Array, state: MAPElitesState, problem: Any
             ) -> tuple[Array, MAPElitesState]:
        p = state.params
        lo, hi = problem.lower, problem.upper
        m, n = self.num_ants, problem.dim
        dtype = problem.dtype
        width = hi - lo
        keys = jax.random.split(key, 7)
        filled = jnp.isfinite(state.archive_cost)
        logits = jnp.where(filled, 0.0, -jnp.inf)
        parent = jax.random.categorical(keys[0], logits, shape=(m,))
        partner = jax.random.categorical(keys[1], logits, shape=(m,))
        xp, xq = state.archive_x[parent], state.archive_x[partner]
        line = p.line_sigma * jax.random.normal(keys[2], (m, 1), dtype) * (xq - xp)
        noise = jax.random.normal(keys[3], (m, n), dtype)
        if self.variation == "isoline":
            x = xp + p.iso_sigma * width * noise + line
        else:
            coords = jnp.asarray(self.cell_coords())
            near = jnp.all(jnp.abs(coords[None, :, :] - coords[parent][:, None, :])
                           <= self.radius, axis=-1)  # (m, C)
            near = near & filled[None, :] & (jnp.arange(self.num_cells)[None, :]
                                             != parent[:, None])
            count = near.sum(axis=1, keepdims=True)
            dist = jnp.abs(state.archive_x[None, :, :] - xp[:, None, :])  # (m, C, n)
            spread = jnp.sum(jnp.where(near[..., None], dist, 0.0), axis=1) / jnp.maximum(
                count, 1)
            sigma = jnp.where(count > 0, p.rho * spread, p.iso_sigma * width)
            drawn = xp + sigma * noise + line
            redraw = (jax.random.uniform(keys[4], (m, n), dtype) < p.p_coordinate) | (
                jnp.arange(n)[None, :] == jax.random.randint(keys[5], (m, 1), 0, n))
            x = jnp.where(redraw, drawn, xp)
        uniform = lo + width * jax.random.uniform(keys[6], (m, n), dtype)
        x = jnp.where(jnp.any(filled), x, uniform)
        return jnp.clip(x, lo, hi), state

    # ----------------------------------------------------------------- tell
    def insert(self, state: MAPElitesState, solutions: Array, fitness: QDEvaluation,
               problem: Any) -> tuple[MAPElitesState, Array]:
        """The archive with ``solutions`` inserted where they beat their cell's elite, and the
        number of cells improved (the elite's fields only; no counters or metrics)."""
        cost = fitness.f.astype(state.archive_cost.dtype)
        desc = fitness.descriptors.astype(state.archive_desc.dtype)
        m, c = cost.shape[0], self.num_cells
        ok = jnp.isfinite(cost) & jnp.all(jnp.isfinite(desc), axis=-1)
        cost = jnp.where(ok, cost, jnp.inf)
        cell = self.cell_index(desc, problem)
        best = jax.ops.segment_min(cost, cell, num_segments=c)  # +inf where no ant
        winner = ok & (cost == best[cell])
        first = jax.ops.segment_min(jnp.where(winner, jnp.arange(m), m), cell, num_segments=c)
        improved = (first < m) & (best < state.archive_cost)
        src = jnp.minimum(first, m - 1)
        state = state.replace(
            archive_x=jnp.where(improved[:, None], solutions.astype(state.archive_x.dtype)[src],
                                state.archive_x),
            archive_cost=jnp.where(improved, best, state.archive_cost),
            archive_desc=jnp.where(improved[:, None], desc[src], state.archive_desc),
        )
        return state, improved.sum().astype(jnp.int32)

    def _tell(self, state: MAPElitesState, solutions: Array, fitness: QDEvaluation,
              problem: Any) -> tuple[MAPElitesState, dict[str, Array]]:
        state, inserted = self.insert(state, solutions, fitness, problem)
        m = archive_metrics(state.archive_cost, float(problem.qd_offset))
        qd = m["qd_score"]
        improved = -qd < state.best_cost
        i = jnp.argmin(state.archive_cost)
        state = state.replace(
            qd_score=qd.astype(state.qd_score.dtype),
            best_solution=state.archive_x[i],
            best_cost=jnp.where(improved, -qd, state.best_cost).astype(jnp.float32),
            stagnation=jnp.where(improved, 0, state.stagnation + 1),
        )
        return state, {**m, "inserted": inserted}

    def best_fitness(self, state: MAPElitesState) -> QDEvaluation:
        """The lowest-cost elite's cost and descriptor (what ``tell`` receives)."""
        i = jnp.argmin(state.archive_cost)
        return QDEvaluation(f=state.archive_cost[i][None], descriptors=state.archive_desc[i][None])

    def immigrate(self, state: MAPElitesState, solutions: Array, fitness: QDEvaluation,
                  key: Array, replace: str = "worst") -> MAPElitesState:
        """Refused: an island's migrants would need their problem to find their cells."""
        raise ConfigError("MAPElites has no island migration: run seeds side by side instead")

    # ----------------------------------------------------------------- reading the archive
    def library(self, state: MAPElitesState, problem: Any) -> dict[str, np.ndarray]:
        """The filled cells of one state (host arrays): ``cell`` (flat index), ``coords``
        (grid coordinates), ``centre`` (descriptor at the cell centre), ``x`` (elite),
        ``cost`` and ``descriptor`` (its measured one)."""
        cost = np.asarray(state.archive_cost)
        if cost.ndim != 1:
            raise ConfigError("MAPElites.library takes one state; for a batch (seeds) pass "
                              "jax.tree.map(lambda a: a[i], state)")
        cells = np.flatnonzero(np.isfinite(cost))
        return {"cell": cells, "coords": self.cell_coords()[cells],
                "centre": self.cell_centres(problem)[cells],
                "x": np.asarray(state.archive_x)[cells], "cost": cost[cells],
                "descriptor": np.asarray(state.archive_desc)[cells]}


def archive_metrics(cost: Array, qd_offset: float) -> dict[str, Array]:
    """``coverage`` (fraction of cells filled), ``qd_score`` (sum of ``qd_offset - cost`` over
    filled cells) and ``max_fitness`` (``-min cost``; ``-inf`` while empty) of an archive's
    costs ``(C,)`` (``+inf``: empty)."""
    filled = jnp.isfinite(cost)
    return {
        "coverage": jnp.mean(filled).astype(jnp.float32),
        "qd_score": jnp.sum(jnp.where(filled, qd_offset - cost, 0.0)).astype(jnp.float32),
        "max_fitness": (-jnp.min(cost)).astype(jnp.float32),
    }


__all__ = ["MAPElites", "MAPElitesParams", "MAPElitesState", "VARIATIONS", "archive_metrics"]
