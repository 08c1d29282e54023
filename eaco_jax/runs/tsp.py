"""The ``tsp`` run: a TSPLIB instance (bundled name or ``.tsp`` path) with the graph colony.

Outputs in ``out``: ``result.json``, ``history.csv``, ``convergence.png`` and ``tour.png``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from eaco_jax.errors import ConfigError
from eaco_jax.runs.base import (
    Built,
    RunKind,
    budget_of,
    check_out,
    check_settings,
    entered,
    params_from,
    setting,
)

PARAMS_HELP = ("hyper-parameters and mechanism switches as KEY=VALUE,... (e.g. "
               "'q0=0.9,use_elitist=true,use_chaos=true'; fields of the strategy's Params)")


@dataclasses.dataclass(frozen=True)
class ColonyDefaults:
    """What ``auto`` settings of ``eaco tsp`` resolve to on a backend (see
    :func:`colony_defaults`)."""

    ants: int
    local_search: str
    ls_best_k: int | None  # None: every ant
    preset: str
    ls_neighbors: int | None = None  # None: the whole candidate lists


#: on a GPU, a budget of at most this many seconds (after compilation) on 700-1,499 cities
#: gets the short-budget row of :data:`COLONY_DEFAULTS`
SHORT_BUDGET_SECONDS = 5.0


@dataclasses.dataclass(frozen=True)
class ColonyRow:
    """One row of :data:`COLONY_DEFAULTS`: the colony for ``min_n <= n < max_n`` cities on
    ``backend`` ("cpu", or "gpu" for any accelerator), when the time budget is at most
    ``max_seconds`` (None: any budget, or none)."""

    backend: str
    min_n: int
    max_n: int | None
    max_seconds: float | None
    colony: ColonyDefaults
    claim: str  # the id in experiments/claims.toml whose measurement chose this row


#: the colonies ``eaco tsp`` resolves ``auto`` to; the first matching row wins. Each row names
#: the claim (experiments/claims.toml, docs/results.md) that measured it; the size boundaries
#: (700, 1,500 cities) lie between measured instances, not at measured crossings
COLONY_DEFAULTS: tuple[ColonyRow, ...] = (
    ColonyRow("cpu", 0, None, None, ColonyDefaults(50, "2opt+oropt", 25, "mmas"),
              "tsp-cpu-pcb442-10s"),
    ColonyRow("gpu", 700, 1500, SHORT_BUDGET_SECONDS,
              ColonyDefaults(256, "or-2opt", None, "mmas", ls_neighbors=8),
              "tsp-gpu-pr1002-3.7s-heldout"),
    # Or-opt moves a segment of up to 3 cities: below 8 cities plain 2-opt
    ColonyRow("gpu", 0, 8, None, ColonyDefaults(768, "2opt", None, "default", ls_neighbors=16),
              "tsp-gpu-pcb442-3s-heldout"),
    ColonyRow("gpu", 8, 700, None,
              ColonyDefaults(768, "or-2opt", None, "default", ls_neighbors=16),
              "tsp-gpu-pcb442-3s-heldout"),
    ColonyRow("gpu", 700, 1500, None, ColonyDefaults(384, "or-2opt", None, "mmas"),
              "tsp-gpu-pr1002-7.5s"),
    ColonyRow("gpu", 1500, None, None, ColonyDefaults(96, "or-2opt", None, "mmas"),
              "tsp-gpu-pr2392-30s-mmas"),
)


@dataclasses.dataclass(frozen=True)
class AntsBand:
    """A colony size for sparse runs of fewer than ``below`` cities, chosen by ``claim``."""

    below: int
    ants: int
    claim: str


@dataclasses.dataclass(frozen=True)
class ConstructionBand:
    """The focused construction for sparse runs of fewer than ``below`` cities: ``max_new_edges``
    moves of kind ``construction``, chosen by ``claim``."""

    below: int
    construction: str
    max_new_edges: int
    claim: str


@dataclasses.dataclass(frozen=True)
class PaceBand:
    """How sparse runs of fewer than ``below`` cities that ``--max-seconds`` alone ends pace
    their compiled calls (``chunk_seconds``) and accept their local search's moves
    (``ls_acceptance``), chosen by ``claim``: both change how fast the iterations come, not
    the tours."""

    below: int
    chunk_seconds: float
    ls_acceptance: str
    claim: str


@dataclasses.dataclass(frozen=True)
class SparseRow:
    """What a sparse-path run on ``backend`` ("cpu", or "gpu" for any accelerator) resolves
    ``--max-new-edges`` (left out) and ``--construction auto`` to, named by the claim whose
    measurement chose it."""

    backend: str
    max_new_edges: int
    construction: str
    claim: str
    #: ``--sparse auto`` takes the sparse path from this many cities (None: the problem
    #: layer's ``SPARSE_MIN_CITIES``, a round size), chosen by ``from_claim``
    from_cities: int | None = None
    from_claim: str = ""
    #: ants whose improvements are merged into one tour each iteration (0: none), part of
    #: the measured setting ``claim`` names
    merge_ants: int = 0
    #: the colony size with this row (``--ants`` left out) by size: the first band whose
    #: ``below`` exceeds the cities; past the last band :data:`COLONY_DEFAULTS` decides
    ants: tuple[AntsBand, ...] = ()
    #: the construction by size: the first band whose ``below`` exceeds the cities; past the
    #: last band, ``construction`` with ``max_new_edges``
    constructions: tuple[ConstructionBand, ...] = ()
    #: the pacing and move acceptance by size (:class:`PaceBand`); past the last band, none
    #: (one iteration per compiled call, greedy rounds in a loop)
    paces: tuple[PaceBand, ...] = ()


#: the sparse path's focused construction by backend, each row chosen on the 10k selection
#: instance: on a GPU 128 new edges as moves with the 96 best ants' improvements merged
#: (lowest mean of three settings over four run seeds), with 1,536 ants below 8,000 cities
#: (chosen on the 5k selection instance), below 12,500 (on the 10k one) and below 20,000 (on
#: the 15k one, at d15112's budget), each the lowest mean of three or four colony sizes over
#: three run seeds; the last bound lies between measured sizes (15,112 and 100,000, where the
#: 96-ant colony was measured). Its construction by size: 64 moves-new (each move inserting
#: an edge the best tour lacks) below 8,000 cities and from 12,500 to 20,000, chosen on the 5k
#: selection instance (lowest mean of six arms) and confirmed on the 15k one; the 10k one kept
#: 128 moves. Below 8,000 cities its calls are paced at 0.25 s with the first greedy rounds
#: unrolled: on the 6k selection instance (30 s on the call clock, two runs each) that and
#: allocating GPU memory on demand (:data:`GPU_ALLOCATOR`) reached the most iterations of five
#: arms. On a CPU
#: 32 new edges city by city
#: (best of three; full construction: ``--construction scan``). The sparse path starts from
#: 3,000 cities on a GPU (it beat the dense path there on a selection and a report instance;
#: smaller sizes are not measured) and from 2,000 on a CPU (it beat the dense path at 2,000,
#: 3,000 and 5,000 on selection instances)
SPARSE_DEFAULTS: tuple[SparseRow, ...] = (
    SparseRow("gpu", 128, "moves", "tsp-10k-h100-select-mne128-merge96-over-bhh-mean",
              from_cities=3000, from_claim="tsp-3k-h100-select-sparse-over-bhh-mean",
              merge_ants=96,
              ants=(AntsBand(8000, 1536, "tsp-5k-h100-select-ants1536-over-bhh-mean"),
                    AntsBand(12500, 1536, "tsp-10k-h100-select-s31-a1536-over-bhh-mean"),
                    AntsBand(20000, 1536, "tsp-15k-h100-select-ants1536-over-bhh-mean")),
              constructions=(
                  ConstructionBand(8000, "moves-new", 64,
                                   "tsp-5k-h100-select-s32-new64-over-bhh-mean"),
                  ConstructionBand(12500, "moves", 128,
                                   "tsp-10k-h100-select-s32-default-over-bhh-mean"),
                  ConstructionBand(20000, "moves-new", 64,
                                   "tsp-15k-h100-select-s32-new64-over-bhh-mean")),
              paces=(PaceBand(8000, 0.25, "unrolled", "tsp-6k-h100-arms-all-iterations-mean"),)),
    SparseRow("cpu", 32, "scan", "tsp-10k-cpu-select-scan32-over-bhh-mean",
              from_cities=2000, from_claim="tsp-cpu-sparse-from-2000-sparse-over-bhh-mean"),
)
#: cities a step of the focused batched search evaluates when ``--ls-focus-width`` is left out
#: and ants change a bounded number of edges (:data:`LS_FOCUS_CLAIM`); 0 turns the focus off
LS_FOCUS_WIDTH = 128
LS_FOCUS_CLAIM = "tsp-10k-h100-select-focus-128-over-bhh"


def sparse_defaults(backend: str) -> SparseRow | None:
    """The :data:`SPARSE_DEFAULTS` row of ``backend`` (None: full construction)."""
    kind = "cpu" if backend == "cpu" else "gpu"
    return next((r for r in SPARSE_DEFAULTS if r.backend == kind), None)


def bands_text(row: SparseRow) -> str:
    """``row``'s colony sizes in words, neighbouring bands of one size joined ("1536 below
    20,000 cities")."""
    joined: list[AntsBand] = []
    for b in row.ants:
        if joined and joined[-1].ants == b.ants:
            joined[-1] = b
        else:
            joined.append(b)
    return ", ".join(f"{b.ants} below {b.below:,} cities" for b in joined)


def band_for(bands: tuple[Any, ...], n: int) -> Any:
    """The first of ``bands`` (each with a ``below``) whose ``below`` exceeds ``n`` cities
    (None: past the last)."""
    return next((b for b in bands if n < b.below), None)


def row_ants(row: SparseRow, n: int) -> int | None:
    """The colony size ``row`` sets for ``n`` cities (None: :data:`COLONY_DEFAULTS` decides)."""
    band = band_for(row.ants, n)
    return None if band is None else band.ants


def paces_text(attr: str) -> str:
    """Where the sparse rows' :class:`PaceBand` set ``attr``, in words (for ``--help``)."""
    return "; ".join(f"{getattr(b, attr)} below {b.below:,} cities on a {r.backend.upper()}"
                     for r in SPARSE_DEFAULTS for b in r.paces) or "nowhere"


def row_pace(row: SparseRow | None, n: int) -> PaceBand | None:
    """The :class:`PaceBand` ``row`` sets for ``n`` cities (None: none)."""
    return None if row is None else band_for(row.paces, n)


#: what ``eaco tsp`` sets for JAX's GPU client unless the environment already says: memory
#: allocated on demand instead of most of the GPU's at the first transfer, which took about a
#: second of a 30 s call on one H100 (the claim named); a CPU ignores it
GPU_ALLOCATOR = {"XLA_PYTHON_CLIENT_PREALLOCATE": "false"}
GPU_ALLOCATOR_CLAIM = "tsp-6k-h100-arms-noprealloc-read-seconds"


def row_construction(row: SparseRow, n: int) -> tuple[str, int]:
    """(construction, max_new_edges) that ``row`` sets for ``n`` cities."""
    band = band_for(row.constructions, n)
    return (row.construction, row.max_new_edges) if band is None else (
        band.construction, band.max_new_edges)


def constructions_text(row: SparseRow) -> str:
    """``row``'s focused construction by size in words."""
    parts = [f"{b.max_new_edges} as {b.construction} below {b.below:,} cities"
             for b in row.constructions]
    last = f"{row.max_new_edges} as {row.construction}"
    return ", ".join(parts + [f"{last} from there" if parts else last])


def _best(k: int | None) -> str:
    return "every tour" if k is None else f"the {k} best"


def _scanned(k: int | None) -> str:
    return "all" if k is None else str(k)


def auto_help(attr: str, show: Callable[[Any], str] = str,
              rows: tuple[ColonyRow, ...] = COLONY_DEFAULTS) -> str:
    """What ``auto`` resolves the :class:`ColonyDefaults` field ``attr`` to, in words, read
    from the table (``--help`` prints it, so the help cannot drift from the table)."""
    parts = []
    for backend, where in (("cpu", "a CPU"), ("gpu", "a GPU")):
        mine = [r for r in rows if r.backend == backend]
        segments: list[list[Any]] = []  # [min_n, max_n, value], equal neighbours merged
        for r in sorted((r for r in mine if r.max_seconds is None), key=lambda r: r.min_n):
            value = getattr(r.colony, attr)
            if segments and segments[-1][2] == value and segments[-1][1] == r.min_n:
                segments[-1][1] = r.max_n
            else:
                segments.append([r.min_n, r.max_n, value])
        pieces = [f"{show(v)} below {hi:,} cities" if hi is not None else
                  (f"else {show(v)}" if len(segments) > 1 else show(v))
                  for _, hi, v in segments]
        for r in (r for r in mine if r.max_seconds is not None):
            value = getattr(r.colony, attr)
            i = next(i for i, (lo, hi, _) in enumerate(segments)
                     if lo <= r.min_n and (hi is None or (r.max_n is not None and r.max_n <= hi)))
            if value == segments[i][2]:
                continue
            lo, hi = segments[i][:2]
            span = "" if (lo, hi) == (r.min_n, r.max_n) else \
                f" for {r.min_n:,}-{r.max_n - 1:,} cities" if r.max_n is not None else \
                f" from {r.min_n:,} cities"
            pieces[i] += f" ({show(value)}{span} with --max-seconds {r.max_seconds:g} or less)"
        parts.append(f"{pieces[0]} on {where}" if len(pieces) == 1 else
                     f"on {where} {', '.join(pieces)}")
    return "; ".join(parts)


#: the iteration budget of a run given neither --iterations, --max-evaluations nor --max-seconds
ITERATIONS = 300
#: iterations per compiled call of a sparse-path run that only --max-seconds ends
SPARSE_CHUNK = 1
#: ... with --chunk-seconds: the compiled call's length, of which each chunk runs what its pace
#: allows (the driver's ``chunk_seconds``)
PACED_CHUNK = 64


@dataclasses.dataclass(frozen=True)
class TspSettings:
    instance: str = setting("eil51", "a .tsp file or a bundled instance name (eil51)",
                            positional=True, metavar="FILE_OR_NAME")
    ants: int | None = setting(None, f"colony size (auto: {auto_help('ants')}"
                               + "".join(f"; on the sparse path's default on a "
                                         f"{r.backend.upper()} "
                                         + bands_text(r)
                                         for r in SPARSE_DEFAULTS if r.ants)
                               + "; chosen for the shortest tour within a time budget, "
                               "docs/results.md)")
    iterations: int | None = setting(None, f"iterations (default {ITERATIONS}; with "
                                     "--max-seconds alone, no cap: time ends the run)")
    seed: int = setting(0, "random seed")
    local_search: str = setting("auto", "local search (2opt: best-improvement batches on the "
                                "candidate lists; or-2opt: the same + Or-opt; 2opt-dlb, "
                                "2opt+oropt: ACOTSP-style with don't-look bits, + Or-opt; "
                                f"auto: {auto_help('local_search')})",
                                choices=("auto", "2opt", "or-2opt", "2opt-dlb", "2opt+oropt",
                                         "none"))
    ls_best_k: int | None = setting(None, "local search on the k shortest tours of each "
                                    f"iteration only (auto: {auto_help('ls_best_k', _best)})")
    ls_neighbors: int | None = setting(None, "candidates per city the local search scans, of "
                                       "each city's candidate list (auto: "
                                       f"{auto_help('ls_neighbors', _scanned)})")
    crossover: str = setting("auto", "tour crossover ('auto': erx with local search, except "
                             "in the mmas preset; else none)",
                             choices=("auto", "erx", "pmx", "none"))
    mutation: str = setting("auto", "tour mutation ('auto': inversion with local search)",
                            choices=("auto", "inversion", "swap", "none"))
    preset: str = setting("auto", "parameter set: default (evidence-based), mmas (as ACOTSP "
                          "runs it), paper (Table 4, every paper mechanism on); auto: "
                          f"{auto_help('preset')}",
                          choices=("auto", "default", "mmas", "paper"))
    max_evaluations: int | None = setting(None, "evaluation budget (a hard cap; replaces "
                                          "--iterations)")
    max_seconds: float | None = setting(None, "time budget in seconds, counted on --clock")
    clock: str = setting("run", "what --max-seconds counts: run (the search loop's compute, "
                         "compilation, reading and the first tour excluded), call (wall time "
                         "from the command's start: start-up, reading, candidate lists, "
                         "compilation and the first tour included)", choices=("run", "call"))
    sparse: str = setting("auto", "distance matrix or not: on (coordinates, candidate lists "
                          "and trails on candidate edges only, memory O(n k)), off (n x n "
                          "matrices), auto (on for EUC_2D, CEIL_2D, ATT from " + "; ".join(
                              f"{r.from_cities:,} cities on a {r.backend.upper()}"
                              for r in SPARSE_DEFAULTS if r.from_cities) + ")",
                          choices=("auto", "on", "off"))
    neighbors: int | None = setting(None, "candidate-list length per city (default 20 with a "
                                    "distance matrix, 16 without)")
    construction: str = setting("auto", "how tours are built: kernel (one Pallas kernel per "
                                "block of ants; compiled on a GPU), scan (a batched step per "
                                "tour position), both the same tours; auto: the dense path's "
                                "measured plan, the sparse path's scan; moves (sparse path, "
                                "with --max-new-edges N: each ant is the best tour changed by "
                                "N 2-opt moves, a loop over the moves, not the cities; "
                                "moves-new: the same, each move inserting an edge the best "
                                "tour lacks; moves-or3opt: segment-insertion moves instead)",
                                choices=("auto", "kernel", "scan", "moves", "moves-new",
                                         "moves-or3opt"))
    max_new_edges: int | None = setting(None, "sparse path: Focused ACO's construction, each "
                                        "ant adds at most this many edges not in the best "
                                        "tour, then follows it (default with --construction "
                                        "auto: " + "; ".join(
                                            f"on a {r.backend.upper()} "
                                            f"{constructions_text(r)}"
                                            for r in SPARSE_DEFAULTS)
                                        + "; --construction scan alone: full construction)")
    ls_focus_width: int | None = setting(None, "with --max-new-edges: the batched local "
                                         "search (2opt, or-2opt) starts from the ends of the "
                                         "edges each ant changed, evaluating at most this "
                                         "many cities a step; 0: every city, every step "
                                         f"(default {LS_FOCUS_WIDTH})")
    merge_ants: int | None = setting(None, "with --max-new-edges: merge the improvements of "
                                     "up to this many ants (largest gains over the best tour, "
                                     "disjoint changes, one tour after the merge) into one "
                                     "tour each iteration; 0: off (default with --construction "
                                     "auto and no --max-new-edges: " + "; ".join(
                                         f"{r.merge_ants} on a {r.backend.upper()}"
                                         for r in SPARSE_DEFAULTS) + "; otherwise 0)")
    reference: str = setting("best", "with --max-new-edges: the tour the ants change, search "
                             "from and merge into: best (the best so far), iteration (the "
                             "last iteration's best, the best so far with probability 0.01, "
                             "as Focused ACO's source solution; it lost to best on the 5k "
                             "selection instance, docs/tsp_large.md)",
                             choices=("best", "iteration"))
    ls_acceptance: str = setting("auto", "with --max-new-edges: how each step of the "
                                 "batched local search accepts its disjoint improving moves: "
                                 "rounds (a loop of greedy rounds), unrolled (the first "
                                 "rounds inline, then the loop: fewer waits on a GPU), "
                                 "sequential (one by one); the same moves either way; auto: "
                                 f"on the sparse path {paces_text('ls_acceptance')}, else "
                                 "rounds",
                                 choices=("auto", "rounds", "unrolled", "sequential"))
    chunk_seconds: float | None = setting(None, "with --max-seconds alone: run in each "
                                          "compiled call about this many seconds' worth of "
                                          "iterations at the last call's pace (the sparse "
                                          f"path: up to {PACED_CHUNK}, instead of one), so "
                                          "fast iterations make fewer host round trips; 0: "
                                          "unpaced; left out: on the sparse path "
                                          f"{paces_text('chunk_seconds')}, else unpaced")
    params: str | None = setting(None, PARAMS_HELP)
    out: str | None = setting(None, "folder for result.json, history.csv and plots")

    def __post_init__(self) -> None:
        if self.chunk_seconds is not None and not (math.isfinite(self.chunk_seconds)
                                                   and self.chunk_seconds >= 0):
            raise ConfigError(f"chunk_seconds must be a finite number >= 0 (0: unpaced), got "
                              f"{self.chunk_seconds}; e.g. --chunk-seconds 0.2")
        check_settings(self, "ants", "iterations", "max_evaluations", "ls_best_k",
                       "ls_neighbors", "neighbors", "max_new_edges")
        if self.ls_focus_width is not None and self.ls_focus_width < 0:
            raise ConfigError(f"ls_focus_width must be >= 0 (0: no focus), got "
                              f"{self.ls_focus_width}; e.g. --ls-focus-width 128")
        if self.merge_ants is not None and (self.merge_ants < 0 or self.merge_ants == 1):
            raise ConfigError(f"merge_ants must be 0 (off) or >= 2, got {self.merge_ants}; "
                              "e.g. --merge-ants 16")
        if self.clock == "call" and self.max_seconds is None:
            raise ConfigError("clock='call' counts the --max-seconds budget from the call; "
                              "give --max-seconds S (or leave --clock run)")


def colony_defaults(n: int, backend: str, seconds: float | None = None) -> ColonyDefaults:
    """The colony that ``--ants`` / ``--local-search`` / ``--ls-best-k`` / ``--preset`` /
    ``--ls-neighbors`` left out (``auto``) resolve to for ``n`` cities and a time budget of
    ``seconds`` (None: no time budget): the first row of :data:`COLONY_DEFAULTS` that fits.

    On a CPU the native don't-look-bit search on the best tours with MMAS as ACOTSP runs it;
    on a GPU the batched or-2opt with fewer ants the larger the tour (each ant's search costs
    more), and a smaller colony scanning fewer candidates when a short budget on a mid-sized
    tour favours fast early polishing.
    """
    kind = "cpu" if backend == "cpu" else "gpu"
    for row in COLONY_DEFAULTS:
        if row.backend == kind and row.min_n <= n and (row.max_n is None or n < row.max_n) \
                and (row.max_seconds is None
                     or (seconds is not None and seconds <= row.max_seconds)):
            return row.colony
    raise AssertionError(f"COLONY_DEFAULTS has no row for {n} cities on {backend}")


def build(s: TspSettings) -> Built:
    import jax

    from eaco_jax.problems.tsp import load_tsplib
    from eaco_jax.problems.tsp_sparse import is_sparse
    from eaco_jax.strategies.graph_eaco import GraphEACO

    sparse = {"auto": None, "on": True, "off": False}[s.sparse]
    for name, value in GPU_ALLOCATOR.items():  # read when the backend starts (unless started)
        os.environ.setdefault(name, value)
    t0 = time.perf_counter()
    backend = jax.default_backend()  # the first call starts the backend
    row = sparse_defaults(backend)
    t1 = time.perf_counter()
    problem = load_tsplib(s.instance, neighbors=s.neighbors, sparse=sparse,
                          sparse_from=row.from_cities if row is not None else None)
    parts = {"backend_seconds": t1 - t0, "read_seconds": time.perf_counter() - t1}
    auto = colony_defaults(int(problem.n), backend, s.max_seconds)
    ants = auto.ants if s.ants is None else int(s.ants)
    ls_neighbors = auto.ls_neighbors if s.ls_neighbors is None else int(s.ls_neighbors)
    local_search = auto.local_search if s.local_search == "auto" else s.local_search
    ls_best_k = auto.ls_best_k if s.ls_best_k is None else int(s.ls_best_k)
    preset = auto.preset if s.preset == "auto" else s.preset
    max_new_edges, construction, merge = s.max_new_edges, s.construction, s.merge_ants
    if row is not None and is_sparse(problem) and max_new_edges is None \
            and construction == "auto":
        construction, max_new_edges = row_construction(row, int(problem.n))
        merge = row.merge_ants if merge is None else merge
        if s.ants is None:
            ants = row_ants(row, int(problem.n)) or ants
    elif row is not None and is_sparse(problem) and s.ants is None \
            and row_ants(row, int(problem.n)) is not None:
        print(f"note: an explicit --max-new-edges or --construction leaves out this backend's "
              f"measured sparse row (its colony size by city count and merged ants): {ants} "
              "ants from the size table; pass --ants to choose", file=sys.stderr)
    pace = row_pace(row, int(problem.n)) if is_sparse(problem) else None
    acceptance = s.ls_acceptance if s.ls_acceptance != "auto" else (
        pace.ls_acceptance if pace is not None else "rounds")
    focus = LS_FOCUS_WIDTH if s.ls_focus_width is None else int(s.ls_focus_width)
    strategy = GraphEACO(num_ants=ants, local_search=local_search, ls_best_k=ls_best_k,
                         ls_neighbors=ls_neighbors, crossover=s.crossover,
                         mutation=s.mutation, preset=preset, max_new_edges=max_new_edges,
                         ls_focus_width=(focus or None) if max_new_edges is not None else None,
                         merge_ants=merge or None, reference=s.reference,
                         ls_acceptance=acceptance,
                         construction=(construction if construction.startswith("moves")
                                       else "ants"),
                         construction_fallback=("auto" if construction.startswith("moves")
                                                else {"scan": "lazy"}.get(construction,
                                                                          construction)))
    params = params_from(strategy, problem, s.params)
    # time alone: the sparse path's iterations take seconds, so the clock is read after each
    # (a chunk of 15 overshot a 20 s budget by 20 s at 10,000 cities on a CPU)
    budget = budget_of(s, s.iterations, {"iterations": ITERATIONS},
                       chunk=SPARSE_CHUNK if is_sparse(problem) else None)
    chunk_seconds = s.chunk_seconds
    if s.chunk_seconds and "chunk_size" not in budget:  # whole chunks
        raise ConfigError("chunk_seconds paces a run that --max-seconds alone ends; drop "
                          "--iterations / --max-evaluations, or drop --chunk-seconds")
    if chunk_seconds is None and pace is not None and "chunk_size" in budget:
        chunk_seconds = pace.chunk_seconds
    if chunk_seconds:  # None or 0: unpaced
        budget["chunk_seconds"] = float(chunk_seconds)
        if is_sparse(problem):
            budget["chunk_size"] = PACED_CHUNK
    return Built(problem, strategy, params, budget, extra={"setup_parts": parts})


def with_resolved_settings(checkpointing: Any, built: Built) -> Any:
    """The checkpointing with the colony that ``auto`` resolved to in its stored settings, so
    that ``eaco resume`` rebuilds this colony on any backend (not the resuming backend's)."""
    from eaco_jax.problems.tsp_sparse import is_sparse

    info = getattr(checkpointing, "run_info", None)
    if not info or not isinstance(info.get("settings"), dict):
        return checkpointing
    st = built.strategy
    settings = {**info["settings"], "ants": int(st.num_ants), "local_search": st.local_search,
                "ls_best_k": st.ls_best_k, "ls_neighbors": st.ls_neighbors,
                "preset": st.preset,
                "chunk_seconds": built.budget.get("chunk_seconds", 0.0),
                **focused_settings(st, info["settings"].get("construction", "auto"),
                                   is_sparse(built.problem))}
    return dataclasses.replace(checkpointing, run_info={**info, "settings": settings})


def focused_settings(st: Any, given: str, sparse: bool) -> dict[str, Any]:
    """The focused construction and search a strategy runs, as the settings that rebuild it
    on any backend: ``max_new_edges``, ``construction`` (the moves it builds with; for full
    tours the ``given`` setting, with a sparse run's "auto" pinned to "scan" so that no
    backend's :data:`SPARSE_DEFAULTS` row applies on resume) and ``ls_focus_width`` (0: no
    focus)."""
    if st.construction.startswith("moves"):
        construction = st.construction
    else:
        construction = "scan" if sparse and given == "auto" else given
    return {"max_new_edges": st.max_new_edges, "construction": construction,
            "ls_focus_width": st.ls_focus_width or 0, "merge_ants": st.merge_ants or 0,
            "reference": st.reference, "ls_acceptance": st.ls_acceptance}


def row_metrics(built: Built, result: Any, row: int) -> dict[str, Any]:
    optimum = built.problem.optimum
    if optimum is None:
        return {}
    cost = float(np.asarray(result.best_cost).reshape(-1)[row])
    return {"gap_percent": 100.0 * (cost / float(optimum) - 1.0),
            "success": bool(cost <= float(optimum))}


def call_start(started_at: float | None, entered_at: float) -> tuple[float, str]:
    """Where "the call" began on the ``time.monotonic()`` clock, and its name: the caller's
    ``started_at``, else this process's start (the ``eaco`` command: interpreter start-up and
    imports included), else ``entered_at`` where the system does not tell the process start."""
    from eaco_jax.driver.stop import process_started_at

    if started_at is not None:
        if isinstance(started_at, bool) or not isinstance(started_at, int | float) \
                or not math.isfinite(started_at) or started_at > entered_at:
            raise ConfigError("started_at must be a time.monotonic() value taken before the "
                              f"call (e.g. started_at=time.monotonic()), got {started_at!r}")
        return float(started_at), "started_at"
    process = process_started_at()
    if process is not None and process <= entered_at:
        return process, "process start"
    return entered_at, "run() entry"


def run(s: TspSettings, *, progress: bool = False, checkpointing: Any = None,
        started_at: float | None = None) -> dict[str, Any]:
    """Solve the instance; returns the JSON record and writes ``s.out`` if set.

    ``started_at`` (a ``time.monotonic()`` value): where the call began, which
    ``clock="call"`` counts ``max_seconds`` from and ``timing.total_seconds`` measures from;
    default this process's start (right for the ``eaco`` command and one run per process;
    in a long-lived session pass ``started_at=time.monotonic()`` at the call).
    """
    entered_at = time.monotonic()
    from eaco_jax.driver.minimize import minimize
    from eaco_jax.problems.tsp_sparse import is_sparse

    origin, origin_name = call_start(started_at, entered_at)
    check_out(s.out)
    built = build(s)
    checkpointing = with_resolved_settings(checkpointing, built)
    budget = dict(built.budget)
    if s.clock == "call":  # the deadline replaces the loop's compute-time rule
        budget["deadline"] = origin + float(budget.pop("max_seconds"))
    with entered(built):
        result = minimize(built.problem, built.strategy, seed=int(s.seed), progress=progress,
                          checkpointing=checkpointing, params=built.params, **budget)
    ended_at = time.monotonic()
    problem = built.problem
    tour, tour_from = returned_tour(result)
    length = int(problem.exact_length(tour))
    rows = int(np.asarray(result.best_cost).size)
    tours = int(built.strategy.num_ants) * int(result.iterations) * rows
    record: dict[str, Any] = {
        "instance": problem.name,
        "n": int(problem.n),
        "ants": int(built.strategy.num_ants),
        "seed": int(s.seed),
        "local_search": built.strategy.local_search,
        "ls_best_k": built.strategy.ls_best_k,
        "ls_neighbors": built.strategy.ls_neighbors,
        "preset": built.strategy.preset,
        **focused_settings(built.strategy, s.construction, is_sparse(problem)),
        "best_length": length,
        "tour_from": tour_from,
        "optimum": problem.optimum,
        "tour": tour.tolist(),
        "iterations": int(result.iterations),
        "evaluations": int(np.asarray(result.evaluations)),
        "max_evaluations": result.max_evaluations,
        "stop_reason": result.stop_reason,
        "seconds": float(result.seconds),
        "compile_seconds": float(result.compile_seconds),
        "seconds_per_iteration": float(result.seconds_per_iteration),
        "timing": timing(s, result, origin, origin_name, entered_at, ended_at,
                         built.extra.get("setup_parts", {})),
        "sparse": is_sparse(problem),
        "neighbors": int(problem.neighbors.shape[1]),
        "tours_per_second": tours / float(result.seconds) if result.seconds > 0 else None,
        **peak_memory(),
        "history_best": np.asarray(result.history.get("best_cost", [])).tolist(),
    }
    if problem.optimum is not None:
        record["gap_percent"] = 100.0 * (length / float(problem.optimum) - 1.0)
    if s.out is not None:
        write_outputs(Path(s.out), record, result.history, s.instance)
    return record


def returned_tour(result: Any) -> tuple[np.ndarray, str]:
    """The tour a run returns and where it came from: the search's best ("search"); where no
    iteration ran (a deadline that passed in setup), the colony's first tour ("first tour":
    the sparse path's Hilbert order after local search), else the cities in file order
    ("file order": the dense path has no tour before its first iteration)."""
    best = np.asarray(result.best_solution, dtype=np.int64)
    if np.all(np.isfinite(np.asarray(result.state.best_cost))):  # the colony's, not the
        return best, "search"  # host's re-check (which also measures the placeholder order)
    first = getattr(result.state, "first_tour", None)
    if first is not None:
        return np.asarray(first, dtype=np.int64).reshape(best.shape), "first tour"
    return best, "file order"


def timing(s: TspSettings, result: Any, origin: float, origin_name: str, entered_at: float,
           ended_at: float, setup_parts: dict[str, float] | None = None) -> dict[str, Any]:
    """Where the wall time went, from the call (``origin``) to the end of the search: start-up
    (the call to :func:`run`: interpreter and imports for the command), compilation, the
    search loop's compute, and setup (the rest: reading the instance, candidate lists, the
    first tour, the host's work between chunks); with the clock and budget the run used.
    ``setup_parts``: the parts of setup timed apart (:func:`build`: ``backend_seconds``, the
    start of JAX's backend, e.g. a GPU's; ``read_seconds``, the instance and its candidate
    lists; the driver: ``between_chunks_seconds``, the host's work between the compiled
    chunks, while the device waits), the rest of setup being the first state's program."""
    total = ended_at - origin
    compile_s = float(result.compile_seconds)
    loop = float(result.seconds) - compile_s
    startup = entered_at - origin
    return {"clock": s.clock, "from": origin_name, "budget_seconds": s.max_seconds,
            "startup_seconds": startup, "setup_seconds": max(total - startup - compile_s - loop,
                                                             0.0),
            "compile_seconds": compile_s, "loop_seconds": loop, "total_seconds": total,
            "setup_parts": {**(setup_parts or {}),
                            "between_chunks_seconds": float(result.host_seconds)}}


def peak_memory() -> dict[str, int | None]:
    """This process's peak host memory (resident set, bytes) and the default device's peak
    bytes in use where its backend reports them (GPUs do; None elsewhere)."""
    import resource
    import sys

    import jax

    try:  # Linux: this program's own peak (ru_maxrss keeps a forking parent's high-water mark)
        with open("/proc/self/status") as f:
            rss = next(int(ln.split()[1]) * 1024 for ln in f if ln.startswith("VmHWM:"))
    except (OSError, StopIteration, ValueError):
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        rss *= 1 if sys.platform == "darwin" else 1024  # bytes on macOS, KiB on Linux
    device = None
    try:
        stats = jax.devices()[0].memory_stats() or {}
        device = int(stats["peak_bytes_in_use"]) if "peak_bytes_in_use" in stats else None
    except Exception:  # noqa: BLE001 - memory_stats is optional per backend
        device = None
    return {"peak_host_bytes": int(rss), "peak_device_bytes": device}


def instance_coords(instance: str) -> np.ndarray | None:
    """City coordinates of a bundled name or ``.tsp`` path (None for EXPLICIT matrices)."""
    from eaco_jax.problems.tsp import DATA_DIR, bundled_path
    from eaco_jax.problems.tsplib import read_tsplib

    text = str(instance)
    bare = "/" not in text and "\\" not in text and not text.endswith(".tsp")
    path = (bundled_path(text) or DATA_DIR / f"{text}.tsp") if bare else Path(text)
    return read_tsplib(path).coords


def write_outputs(folder: Path, record: dict[str, Any], history: dict[str, np.ndarray],
                  instance: str) -> None:
    """``result.json``, ``history.csv``, ``convergence.png`` and ``tour.png`` in ``folder``."""
    from eaco_jax import plots
    from eaco_jax.outputs import write_history_csv, write_json

    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / "result.json", record)
    write_history_csv(folder / "history.csv", history)
    plots.convergence(history, folder / "convergence.png", optimum=record.get("optimum"),
                      title=f"{record['instance']}: tour length", ylabel="tour length")
    coords = instance_coords(instance)
    if coords is not None:
        plots.tour(coords, np.asarray(record["tour"]), folder / "tour.png",
                   title=f"{record['instance']}: length {record['best_length']}")


def summary(record: dict[str, Any]) -> str:
    gap = record.get("gap_percent")
    return (f"{record['instance']}: best length {record['best_length']}"
            + (f" (optimum {record['optimum']:g}, gap {gap:.2f}%)" if gap is not None else "")
            + f" in {record['iterations']} iterations, {record['seconds']:.1f} s"
            + (f" ({t['total_seconds']:.1f} s from the call, budget {t['budget_seconds']:g} s"
               f" on the {t['clock']} clock)"
               if (t := record.get("timing")) and t.get("budget_seconds") is not None else "")
            + (f", stopped by {record['stop_reason']}" if record.get("stop_reason") else "")
            + (f"; {record['tours_per_second']:,.0f} tours/s"
               if record.get("tours_per_second") else "")
            + (f", peak memory {record['peak_host_bytes'] / 2**20:,.0f} MiB host"
               if record.get("peak_host_bytes") else "")
            + (f", {record['peak_device_bytes'] / 2**20:,.0f} MiB device"
               if record.get("peak_device_bytes") else ""))


KIND = RunKind("tsp", TspSettings, build, run, row_metrics, summary)
