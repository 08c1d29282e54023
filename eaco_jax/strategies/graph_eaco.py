"""EACO on a construction graph (TSP): the paper's enhanced elitist-mutated ant colony.

One iteration (``ask`` then ``tell``):

1. ask: the chaos variables advance one logistic-map step; choice weights tau^alpha eta^beta
   are computed once; all ants build tours in one ``lax.scan`` (Eq. 2 with tabu masks and the
   q0 rule, selection perturbed by chaos), together with one extra ant that follows the
   pheromone alone greedily (Eq. 6, its length is L_pn of Eq. 5); tours then undergo crossover
   with the best-so-far tour (ERX or PMX) and mutation (inversion or swap) at self-adaptive rates
   (better-than-average ants are changed less, the iteration best not at all), and 2-opt local
   search.
2. tell: best-so-far record; MMAS restart counter; evaporation rate from the stagnation
   schedule; local update (Eq. 68-70), global update (Eq. 71), elitist reinforcement
   (Eq. 73-74) with the elitist-only deposit condition (Eq. 3-4) and the adaptive weight (Eq. 5);
   MAX-MIN bounds (Eq. 7); restart of the trails on long stagnation; population diversity.

Tours are built on the problem's nearest-neighbour candidate lists (``candidate_lists=True``,
as ACOTSP does: Eq. 2 over the allowed candidates, the best allowed node when all candidates
are tabu; the pheromone-greedy ant of Eq. 6 likewise); ``candidate_lists=False`` applies Eq. 2
over all nodes at O(n) more work per step.

Sparse path: on a problem without a distance matrix (``problems.tsp_sparse.SparseTSP``, memory
O(n k)) the trails and choice information live on the candidate edges only ((n, k) arrays,
``ops.pheromone``), tours are built by ``ops.construction_sparse`` (its fallback, when every
candidate is tabu, follows the best tour so far, O(1) per step), distances are computed from
the coordinates, and the colony starts from a Hilbert-curve tour polished by the local search
(``seed_tour``). With candidate lists of every other city it builds the tours of the dense path.

Every mechanism has a boolean switch in :class:`GraphParams` (traced, so ablations and sweeps vmap).
Operators that cost compute (crossover, mutation, local search) are static fields: "none"
removes them from the compiled program.

Defaults (differences from the paper's Table 4 and why):
  * MAX-MIN style: the global update (Eq. 71) is the main deposit, with alpha_g = rho = 0.2;
    trails start at tau_max (``init_at_tau_max = 1``) instead of tau0 = 1/(n L_nn), and are
    re-initialised after ``restart_after`` iterations without improvement. Starting at tau0
    makes the first deposit dominate and the colony converge in a few iterations; MMAS's
    tau_max start and restarts are what makes ant colonies with 2-opt reliable on TSPLIB.
  * The global update deposits on the iteration-best tour, and on the best-so-far tour every
    ``gb_every`` iterations (``gb_every = 1`` is the paper's global-best-only Eq. 71).
  * Without local search, MMAS as ACOTSP runs it: alpha_g = rho = 0.02; the deposit every
    ``gb_every = 25`` iterations and the stagnation count use the best tour since the last
    restart (``use_restart_best``); a restart needs 250 iterations without improving it *and*
    converged trails (lambda-branching factor below ``restart_branching = 1.00001``); tau_min
    assumes (k + 1) / 2 choices per step on k candidates (``branching``): ACOTSP's own
    rules, which reach its quality in its time (claims ``tsp-no-ls-*``, docs/results.md).
  * beta = 2 (ACOTSP's default; Table 4's 5 converges to worse tours in our runs).
  * Q = 1 instead of 100: the same units (1/length) as Eq. 71, see :mod:`eaco_jax.ops.pheromone`.
  * q0 = 0 (Table 3's best q0 = 0.8 is for the constrained problem G1; it makes TSP colonies
    converge prematurely); local update, elitist reinforcement, the Eq. 3-4 condition, the
    adaptive weight, chaos and the evaporation schedule are implemented but off by default
    (the ablation claims in docs/results.md); crossover/mutation are on with the paper's p_c = 0.6,
    p_m = 0.5 under self-adaptive scaling when 2-opt is on, and off without it (``"auto"``).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.errors import ConfigError, ProblemError
from eaco_jax.ops import chaos, pheromone
from eaco_jax.ops.construction import (
    choice_weights,
    construct_tours,
    heuristic_log_eta,
    tour_lengths,
)
from eaco_jax.ops.construction_moves import PLANS as MOVES_PLANS
from eaco_jax.ops.construction_moves import construct_tours_moves
from eaco_jax.ops.construction_sparse import construct_tours_sparse, hilbert_tour
from eaco_jax.ops.local_search import ACCEPTANCES as LS_ACCEPTANCES
from eaco_jax.ops.local_search import LOOPS as LS_LOOPS
from eaco_jax.problems.tsp import DEFAULT_NEIGHBORS
from eaco_jax.problems.tsp_sparse import is_sparse
from eaco_jax.strategies.base import (
    AT_LEAST_ONE,
    BOOL,
    NONNEG,
    POSITIVE,
    UNIT,
    Range,
    State,
    Strategy,
    adopt_best,
    as_params,
    base_fields,
    record_best,
)

Array = jax.Array

LOCAL_SEARCHES = ("2opt", "or-2opt", "2opt-dlb", "2opt+oropt", "none")
#: named parameter sets of GraphEACO.default_params
PRESETS = ("default", "mmas", "paper")
CROSSOVERS = ("erx", "pmx", "none")
MUTATIONS = ("inversion", "swap", "none")
#: how ants build tours on the sparse path (GraphEACO.construction)
CONSTRUCTIONS = ("ants", "moves", "moves-new", "moves-or3opt")
#: the tour focused ants change (:attr:`GraphEACO.reference`)
REFERENCES = ("best", "iteration")


@struct.dataclass
class GraphParams:
    """Traced hyper-parameters; defaults are those with local search (see
    :meth:`GraphEACO.default_params` for the values without it). Switches are booleans."""

    alpha: Array = 1.0  # pheromone weight in Eq. 2
    beta: Array = 2.0  # heuristic weight in Eq. 2
    rho: Array = 0.2  # evaporation rate (local update, elitist update)
    q0: Array = 0.0  # pseudo-random proportional rule
    alpha_g: Array = 0.2  # global evaporation of Eq. 71
    sigma: Array = 6.0  # number of elitist ants, Eq. 74
    q: Array = 1.0  # deposit factor Q
    p_best: Array = 0.05  # MMAS: probability of rebuilding the best tour at the limits
    branching: Array = 0.0  # MMAS tau_min: average choices per step (0: n/2 - 1)
    chaos_strength: Array = 0.1  # selection factor in [1 - s, 1 + s]
    p_crossover: Array = 0.6
    p_mutation: Array = 0.5
    restart_after: Array = 50.0  # iterations without improvement before a trail restart
    restart_branching: Array = 0.0  # ... and only once the trails' lambda-branching factor
    # is below this (converged; ACOTSP's 1.00001); 0: no convergence test
    gb_every: Array = 3.0  # global update uses the best-so-far tour every gb_every iterations
    stagnation_window: Array = 50.0  # evaporation schedule: iterations to full slow-down
    evaporation_slowdown: Array = 0.5  # evaporation schedule strength in [0, 1)
    use_restart_best: Array = False  # MMAS: deposit and count stagnation on the best tour
    # since the last restart instead of the best-so-far tour
    use_local_update: Array = False  # Eq. 68-70
    use_global_update: Array = True  # Eq. 71
    use_elitist: Array = False  # Eq. 73-74
    use_deposit_condition: Array = False  # Eq. 3-4
    use_adaptive_weight: Array = False  # Eq. 5-6
    use_bounds: Array = True  # Eq. 7
    use_chaos: Array = False  # logistic-map perturbation of the choice weights
    use_evaporation_schedule: Array = False
    use_restart: Array = True
    use_adaptive_rates: Array = True  # self-adaptive crossover / mutation rates
    init_at_tau_max: Array = True

    #: documented ranges, checked on the host before a run (concrete values only)
    RANGES: ClassVar[dict[str, Range]] = {
        "alpha": Range(0.0, 10.0), "beta": Range(0.0, 20.0), "rho": Range(0.0, 1.0, True),
        "q0": UNIT, "alpha_g": UNIT, "sigma": NONNEG, "q": POSITIVE,
        "p_best": Range(0.0, 1.0, True, True), "branching": NONNEG,
        "chaos_strength": Range(0.0, 1.0, open_high=True), "p_crossover": UNIT,
        "p_mutation": UNIT, "restart_after": AT_LEAST_ONE, "restart_branching": NONNEG,
        "gb_every": AT_LEAST_ONE, "stagnation_window": POSITIVE,
        "evaporation_slowdown": Range(0.0, 1.0, open_high=True),
        **{name: BOOL for name in (
            "use_restart_best", "use_local_update", "use_global_update", "use_elitist",
            "use_deposit_condition", "use_adaptive_weight", "use_bounds", "use_chaos",
            "use_evaporation_schedule", "use_restart", "use_adaptive_rates",
            "init_at_tau_max")},
    }


@struct.dataclass
class GraphState(State):
    tau: Array  # (n, n) pheromone
    chaos: Array  # (m, n) logistic-map variables
    iter_best_cost: Array  # best tour length of the last iteration (Eq. 3-4)
    pheromone_tour_length: Array  # L_pn of the last iteration (Eq. 6 tour; with the adaptive
    # weight off, the greedy tour on the colony weights, which nothing uses)
    since_improvement: Array  # restart counter
    restart_best_solution: Array  # best tour since the last restart
    restart_best_cost: Array
    restarts: Array


@struct.dataclass
class SparseGraphState(GraphState):
    """The state on a sparse problem: ``tau`` is (n, k), on the candidate edges."""

    first_tour: Array  # (n,) the Hilbert-curve tour after local search: the first reference
    source: Array  # (n,) the last iteration's best tour (the first tour before one)


def acotsp_ls_branching(n: int, p_best: float = 0.05) -> float:
    """The ``branching`` that makes tau_min = tau_max / (2 n), ACOTSP's MMAS limit with local
    search (:func:`eaco_jax.ops.pheromone.mmas_bounds` sets tau_min = tau_max (1 - r) /
    (branching r), r = p_best^(1/n)); about 6 for any n at p_best = 0.05."""
    root = p_best ** (1.0 / n)
    return 2.0 * n * (1.0 - root) / root


def paper_params() -> GraphParams:
    """The paper's EACO: Table 4's values and every mechanism of the paper on.

    alpha = 1, beta = 5, rho = 0.2, Q = 100, tau0 = 1/(n L_nn) (no start at tau_max),
    p_c = 0.6, p_m = 0.5 (Table 4); q0 = 0.8 (Table 3's best); local update (Eq. 68-70),
    global update on the global-best tour every iteration (Eq. 71, alpha_g = rho: the paper
    gives no separate value), elitist ants (Eq. 73-74, sigma = 6: not given in the paper),
    elitist-only deposit (Eq. 3-4), adaptive weight (Eq. 5-6), MAX-MIN bounds (Eq. 7), chaos
    and the dynamic evaporation; no MMAS restarts (the paper has none).
    """
    on = True
    return GraphParams(
        alpha=1.0, beta=5.0, rho=0.2, q0=0.8, alpha_g=0.2, sigma=6.0, q=100.0,
        p_crossover=0.6, p_mutation=0.5, gb_every=1.0,
        use_local_update=on, use_global_update=on, use_elitist=on, use_deposit_condition=on,
        use_adaptive_weight=on, use_bounds=on, use_chaos=on, use_evaporation_schedule=on,
        use_restart=False, use_restart_best=False, use_adaptive_rates=on,
        init_at_tau_max=False)


def _f(x: float) -> Array:
    return jnp.asarray(x, jnp.float32)


def _candidate_log_eta(problem: Any) -> Array:
    """(n, k) log(eta) of the candidate edges, computed from the coordinates: the entries of
    :func:`~eaco_jax.ops.construction.heuristic_log_eta` on them (zero distances as 0.5)."""
    nbr = problem.neighbors
    d = problem.dist[jnp.arange(nbr.shape[0])[:, None], nbr]
    return -jnp.log(jnp.maximum(d.astype(jnp.float32), 0.5))


@dataclasses.dataclass(frozen=True)
class GraphEACO(Strategy):
    """EACO colony for graph problems (TSP). See the module docstring for the algorithm."""

    num_ants: int = 40
    local_search: str = "2opt"
    #: "auto": ERX / inversion with local search, "none" without (without 2-opt they cost
    #: more time per iteration than they return in quality at a fixed time)
    crossover: str = "auto"
    mutation: str = "auto"
    #: cap on 2-opt improving moves per tour per iteration (None: run to a local optimum)
    max_ls_moves: int | None = None
    #: local search on the ls_best_k shortest tours of each iteration only (None: all ants)
    ls_best_k: int | None = None
    #: "2opt" / "or-2opt": most disjoint improving moves one batched step applies per tour
    #: (1 = classic best improvement; see ops/local_search.py); 64 was best of 32 / 64 / 128
    #: (claims tsp-gpu-pr1002-7.5s-mps64 and -mps32)
    ls_moves_per_step: int = 64
    #: candidates per city that the local search scans: the first ls_neighbors of the
    #: problem's nearest-neighbour lists (None: all of them)
    ls_neighbors: int | None = None
    #: build tours on the problem's nearest-neighbour candidate lists (see construction.py)
    candidate_lists: bool = True
    #: how the tours are built ("auto", "lazy", "dense", "backup", "compact", "kernel"; see
    #: construction.construct_tours): a cost choice only, every plan builds the same tours;
    #: "auto" is the backend's row of construction.AUTO_PLANS (each row names its claim)
    construction_fallback: str = "auto"
    #: named parameter set of :meth:`default_params` (:data:`PRESETS`); "paper" also turns
    #: ERX crossover and inversion mutation on without local search ("auto")
    preset: str = "default"
    #: sparse problems: start from a Hilbert-curve tour polished by the local search (the
    #: first iteration's ant 0 and the fallback's first reference); None: on for them
    seed_tour: bool | None = None
    #: sparse problems: Focused ACO's construction, each ant adds at most this many edges
    #: that are not in the best tour so far, then follows it (None: full construction)
    max_new_edges: int | None = None
    #: sparse problems, how the ants build: "ants" (city by city, ``construction_sparse``),
    #: "moves" (the best tour so far changed by ``max_new_edges`` 2-opt moves each,
    #: ``construction_moves``: a loop over the moves, not over the n cities), "moves-new"
    #: (the same, each move inserting an edge the best tour lacks) or "moves-or3opt" (the
    #: same as "moves" with segment-insertion moves, three new edges each)
    construction: str = "ants"
    #: sparse problems with ``max_new_edges``: the batched searches ("2opt", "or-2opt") start
    #: from the ends of the edges an ant changed, with don't-look bits, evaluating at most this
    #: many cities a step (None: every city, every step; the don't-look-bit searches always
    #: start from those cities)
    ls_focus_width: int | None = None
    #: sparse problems with ``max_new_edges``: merge the improvements of up to this many ants
    #: (the largest gains over the best tour, touching disjoint cities, the merge one tour)
    #: into one tour that takes the worst ant's place (``ops/tour_merge.py``; None: off)
    merge_ants: int | None = None
    #: the focused batched search without the colony waiting for its slowest ant:
    #: (first_steps, batch), see ``ops.local_search.two_opt`` (the same tours; a cost choice;
    #: None: one vmapped loop)
    ls_compact: tuple[int, int] | None = None
    #: how the "moves" constructions hold an ant's tour between moves: "arrays" (rewritten
    #: at each move) or "pieces" (a piecewise map of the reference's positions, O(moves) a
    #: move); the same tours, a cost choice (``ops.construction_moves.PLANS``; with
    #: ``ls_loop`` chosen by claims tsp-5k/15k-h100-pieces-colony-ask-ratio)
    moves_plan: str = "pieces"
    #: how the focused batched search loops over its steps: "ants" (a vmapped loop per tour)
    #: or "colony" (one loop over the colony, without the vmapped loop's select of every
    #: ant's carry after each step); the same tours, a cost choice (``ops.local_search.LOOPS``;
    #: with ``moves_plan`` chosen by claims tsp-5k/15k-h100-pieces-colony-ask-ratio)
    ls_loop: str = "colony"
    #: how a step of the batched searches accepts its disjoint moves: "rounds" (a loop of
    #: parallel rounds) or "unrolled" (its first rounds inline, skipping a GPU's wait on the
    #: loop's test); the same tours, a cost choice (``ops.local_search.ACCEPTANCES``)
    ls_acceptance: str = "rounds"
    #: sparse problems with ``max_new_edges``: the tour the ants change, search from and merge
    #: into: "best" (the best so far) or "iteration" (the last iteration's best, and with
    #: probability ``reference_best_prob`` the best so far: Focused ACO's source solution,
    #: which can get worse and so leaves a local optimum the best so far holds on to)
    reference: str = "best"
    reference_best_prob: float = 0.01
    problem_kind: ClassVar[str] = "graph"

    def __post_init__(self) -> None:
        if self.preset not in PRESETS:
            raise ConfigError(f"preset={self.preset!r} is not one of {PRESETS}")
        # ERX / inversion come with local search, except in MMAS as ACOTSP runs it
        with_ls = ((self.local_search != "none" and self.preset != "mmas")
                   or self.preset == "paper")
        for name, on in (("crossover", "erx"), ("mutation", "inversion")):
            if getattr(self, name) == "auto":
                object.__setattr__(self, name, on if with_ls else "none")
        if self.num_ants < 1:
            raise ConfigError(f"num_ants must be >= 1, got {self.num_ants}")
        if self.ls_best_k is not None and self.ls_best_k < 1:
            raise ConfigError(f"ls_best_k must be >= 1 or None, got {self.ls_best_k}")
        if self.ls_neighbors is not None and self.ls_neighbors < 1:
            raise ConfigError(f"ls_neighbors must be >= 1 or None, got {self.ls_neighbors}")
        if self.max_new_edges is not None and self.max_new_edges < 1:
            raise ConfigError(f"max_new_edges must be >= 1 or None, got {self.max_new_edges}")
        if self.construction not in CONSTRUCTIONS:
            raise ConfigError(f"construction={self.construction!r} is not one of "
                              f"{CONSTRUCTIONS}")
        if self.construction != "ants" and self.max_new_edges is None:
            raise ConfigError(f"construction={self.construction!r} applies max_new_edges "
                              "moves per ant: give --max-new-edges N (max_new_edges=N)")
        if self.ls_moves_per_step < 1:
            raise ConfigError(f"ls_moves_per_step must be >= 1, got {self.ls_moves_per_step}")
        if self.ls_focus_width is not None and self.ls_focus_width < 1:
            raise ConfigError(f"ls_focus_width must be >= 1 or None, got {self.ls_focus_width}")
        if self.ls_loop not in LS_LOOPS:
            raise ConfigError(f"ls_loop={self.ls_loop!r} is not one of {LS_LOOPS}")
        if self.ls_acceptance not in LS_ACCEPTANCES:
            raise ConfigError(f"ls_acceptance={self.ls_acceptance!r} is not one of "
                              f"{LS_ACCEPTANCES}")
        if self.moves_plan not in MOVES_PLANS:
            raise ConfigError(f"moves_plan={self.moves_plan!r} is not one of {MOVES_PLANS}")
        if self.ls_compact is not None:
            if len(self.ls_compact) != 2 or int(self.ls_compact[0]) < 0 \
                    or int(self.ls_compact[1]) < 1:
                raise ConfigError(f"ls_compact must be (first_steps >= 0, batch >= 1) or None, "
                                  f"got {self.ls_compact!r}")
            # a tuple of ints: a static argument of the compiled search (a list is unhashable)
            object.__setattr__(self, "ls_compact", tuple(int(x) for x in self.ls_compact))
        if self.reference not in REFERENCES:
            raise ConfigError(f"reference={self.reference!r} is not one of {REFERENCES}")
        if not 0.0 <= float(self.reference_best_prob) <= 1.0:
            raise ConfigError(f"reference_best_prob must be in [0, 1], got "
                              f"{self.reference_best_prob!r}")
        if self.merge_ants is not None:
            if isinstance(self.merge_ants, bool) or not isinstance(self.merge_ants, int) \
                    or self.merge_ants < 2:
                raise ConfigError(f"merge_ants must be an integer >= 2 or None, got "
                                  f"{self.merge_ants!r}")
            if self.max_new_edges is None:
                raise ConfigError("merge_ants merges ants that changed a few edges of the best "
                                  "tour: give --max-new-edges N (max_new_edges=N)")
        for name, value, allowed in (
            ("local_search", self.local_search, LOCAL_SEARCHES),
            ("crossover", self.crossover, CROSSOVERS),
            ("mutation", self.mutation, MUTATIONS),
        ):
            if value not in allowed:
                raise ConfigError(f"{name}={value!r} is not one of {allowed}")

    # ------------------------------------------------------------------ params
    def default_params(self, problem: Any = None, preset: str | None = None) -> GraphParams:
        """The parameters of ``preset`` (default: the strategy's ``preset`` field).

        "mmas": MAX-MIN ant system as ACOTSP runs it. Without local search the ACOTSP no-LS
        settings; with it ACOTSP's local-search settings (``acotsp.c``): tau_min =
        tau_max / (2 n) (:func:`acotsp_ls_branching`), a restart once the trails have
        converged (lambda-branching factor below 1.00001) and the best tour since the last
        restart is 250 iterations old, deposits on that restart-best tour; crossover and
        mutation off (``"auto"``). "paper": Table 4 and every mechanism of the paper on
        (:func:`paper_params`). "default": the evidence-based default
        (``experiments/ablation.py``): with local search the module docstring's values (a
        restart after 50 iterations without a new best, n / 2 - 1 choices in tau_min), which
        the GPU time-to-quality runs use; without it the same as "mmas".
        """
        preset = self.preset if preset is None else preset
        if preset not in PRESETS:
            raise ConfigError(f"preset={preset!r} is not one of {PRESETS}")
        if preset == "paper":
            return as_params(paper_params())
        params = GraphParams()
        if self.local_search == "none":
            k = getattr(problem, "neighbors", None)
            k = DEFAULT_NEIGHBORS if k is None else int(k.shape[1])
            params = params.replace(
                rho=0.02, alpha_g=0.02, branching=float((k + 1) // 2), restart_after=250.0,
                restart_branching=1.00001, use_restart_best=True, gb_every=25.0)
        elif preset == "mmas":
            n = getattr(problem, "n", None)
            if n is None:
                raise ConfigError("preset='mmas' with local search needs the problem "
                                  "(tau_min depends on its size): default_params(problem)")
            params = params.replace(
                branching=acotsp_ls_branching(int(n), float(params.p_best)),
                restart_after=250.0, restart_branching=1.00001, use_restart_best=True)
        return as_params(params)

    def inactive_params(self, params: GraphParams) -> dict[str, str]:
        """Fields without effect under these switches -> the switch that makes them act."""

        def on(name: str) -> bool:
            return bool(jnp.all(jnp.asarray(getattr(params, name))))

        dead: dict[str, str] = {}
        rules = (
            (("rho", "q"), on("use_local_update") or on("use_elitist"),
             "use_local_update or use_elitist"),
            (("sigma", "use_deposit_condition", "use_adaptive_weight"), on("use_elitist"),
             "use_elitist"),
            (("chaos_strength",), on("use_chaos"), "use_chaos"),
            (("alpha_g", "gb_every"), on("use_global_update"), "use_global_update"),
            (("restart_after", "restart_branching"), on("use_restart"), "use_restart"),
            (("stagnation_window", "evaporation_slowdown"), on("use_evaporation_schedule"),
             "use_evaporation_schedule"),
            (("p_best", "branching"), on("use_bounds"), "use_bounds"),
            (("p_crossover",), self.crossover != "none", "crossover='erx' or 'pmx'"),
            (("p_mutation",), self.mutation != "none", "mutation='inversion' or 'swap'"),
            (("use_adaptive_rates",), self.crossover != "none" or self.mutation != "none",
             "a crossover or mutation operator"),
        )
        for names, active, switch in rules:
            if not active:
                dead.update(dict.fromkeys(names, switch))
        return dead

    # ------------------------------------------------------------------ init
    def prepare(self, problem: Any) -> Any:
        if is_sparse(problem):
            nbr = getattr(problem, "neighbors", None)
            if nbr is None or nbr.ndim != 2 or nbr.shape[0] != problem.n or problem.n < 3:
                raise ProblemError("a sparse graph problem needs (n, k) candidate lists")
            if not self.candidate_lists:
                raise ConfigError("candidate_lists=False needs a distance matrix; the sparse "
                                  "path builds tours on the candidate lists")
            return problem
        if self.construction != "ants":
            raise ConfigError(f"construction={self.construction!r} needs the sparse path "
                              "(no distance matrix): pass --sparse on to eaco tsp, or "
                              "sparse=True to load_tsplib")
        if self.max_new_edges is not None:
            raise ConfigError("max_new_edges (focused construction) needs the sparse path "
                              "(no distance matrix): pass --sparse on to eaco tsp, or "
                              "sparse=True to load_tsplib")
        dist = getattr(problem, "dist", None)
        shape = getattr(dist, "shape", ())
        if len(shape) != 2 or shape[0] != shape[1] or shape[0] < 3:
            raise ProblemError(
                f"graph problem needs an (n, n) distance matrix, n >= 3; got {shape}")
        return problem

    def _sparse_plan(self) -> str:
        """The sparse construction's plan: the kernel only where ``construction_fallback`` is
        "kernel"; else the scan ("auto" included: the sparse kernel equals the scan in Pallas'
        interpreter, but no compiled run on a GPU has checked or timed it yet, so no default
        picks it)."""
        return "kernel" if self.construction_fallback == "kernel" else "scan"

    def _seeded(self, problem: Any) -> bool:
        return is_sparse(problem) and self.seed_tour is not False

    def _init_sparse(self, key: Array, problem: Any, params: GraphParams) -> SparseGraphState:
        """:meth:`_init` on candidate edges: (n, k) trails, the nearest-neighbour tour on the
        candidate lists (the Hilbert tour's order where they run out), the first tour."""
        dist, nbr = problem.dist, problem.neighbors
        n = problem.n
        log_eta = _candidate_log_eta(problem)
        k_chaos, key = jax.random.split(key)
        hilbert = hilbert_tour(problem.coords)
        nn_weights = choice_weights(jnp.ones_like(log_eta), log_eta, _f(0.0), _f(1.0))
        nn_tour = construct_tours_sparse(k_chaos, nn_weights, nbr, jnp.zeros((1,), jnp.int32),
                                         hilbert, q0=1.0, plan=self._sparse_plan())
        nn_length = tour_lengths(dist, nn_tour)[0]
        first = hilbert
        if self._seeded(problem):
            first = self._local_search(hilbert[None], problem,
                                       jax.random.fold_in(k_chaos, 1))[0]
        tau_max, _ = self._bounds(params.replace(use_bounds=jnp.bool_(True)), nn_length, n)
        tau0 = jnp.where(params.init_at_tau_max, tau_max, pheromone.initial_tau(n, nn_length))
        return SparseGraphState(**self._fresh_fields(key, k_chaos, params, n, nn_length),
                                tau=jnp.full(nbr.shape, tau0, jnp.float32), first_tour=first,
                                source=first)

    def _fresh_fields(self, key: Array, k_chaos: Array, params: GraphParams, n: int,
                      nn_length: Array) -> dict[str, Any]:
        """The state fields a dense and a sparse colony start with alike (all but the trails)."""
        return dict(
            **base_fields(key, params, jnp.arange(n, dtype=jnp.int32)),
            chaos=chaos.logistic_init(k_chaos, (self.num_ants, n)),
            iter_best_cost=jnp.asarray(jnp.inf, jnp.float32),
            pheromone_tour_length=nn_length,
            since_improvement=jnp.zeros((), jnp.int32),
            restart_best_solution=jnp.arange(n, dtype=jnp.int32),
            restart_best_cost=jnp.asarray(jnp.inf, jnp.float32),
            restarts=jnp.zeros((), jnp.int32),
        )

    def _init(self, key: Array, problem: Any, params: GraphParams) -> GraphState:
        if is_sparse(problem):
            return self._init_sparse(key, problem, params)
        dist = jnp.asarray(problem.dist, jnp.float32)
        n = dist.shape[0]
        log_eta = heuristic_log_eta(dist)
        k_chaos, key = jax.random.split(key)
        # nearest-neighbour tour from node 0: greedy on eta alone
        nn_weights = choice_weights(jnp.ones_like(dist), log_eta, _f(0.0), _f(1.0))
        nn_tour = construct_tours(k_chaos, nn_weights, jnp.zeros((1,), jnp.int32), q0=1.0)
        nn_length = tour_lengths(dist, nn_tour)[0]
        # the MMAS tau_max even when the bounds are off (else the trails would start at +inf)
        tau_max, _ = self._bounds(params.replace(use_bounds=jnp.bool_(True)), nn_length, n)
        tau0 = jnp.where(params.init_at_tau_max, tau_max, pheromone.initial_tau(n, nn_length))
        return GraphState(**self._fresh_fields(key, k_chaos, params, n, nn_length),
                          tau=jnp.full((n, n), tau0, jnp.float32))

    def _bounds(self, p: GraphParams, best_length: Array, n: int) -> tuple[Array, Array]:
        """MMAS limits for the rules that are on (tau_max = steady state of the best tour)."""
        scale = p.use_global_update + p.use_elitist * p.q * (p.sigma + 1.0)
        scale = jnp.maximum(scale, 1.0)
        tau_max, tau_min = pheromone.mmas_bounds(best_length, n, p.p_best, scale, p.branching)
        on = p.use_bounds
        return jnp.where(on, tau_max, jnp.inf), jnp.where(on, tau_min, 1e-30)

    # ------------------------------------------------------------------ ask
    def _ask(self, key: Array, state: GraphState, problem: Any) -> tuple[Array, GraphState]:
        p = state.params
        m, n = self.num_ants, state.tau.shape[0]
        sparse = is_sparse(problem)
        dist = problem.dist if sparse else jnp.asarray(problem.dist, jnp.float32)
        log_eta = _candidate_log_eta(problem) if sparse else heuristic_log_eta(dist)
        # the ACOTSP-style searches draw a random city order: a fifth key (the other kinds keep
        # the four-way split, so their tours are unchanged)
        dlb = self.local_search in ("2opt-dlb", "2opt+oropt")
        k_start, k_build, k_cx, k_mut, *k_ls = jax.random.split(key, 5 if dlb else 4)

        x = chaos.logistic_step(state.chaos)
        factor = jnp.where(p.use_chaos, chaos.perturbation(x, p.chaos_strength), 1.0)
        factor = jnp.concatenate([factor, jnp.ones((1, n), jnp.float32)], axis=0)

        weights = choice_weights(state.tau, log_eta, p.alpha, p.beta)
        # Eq. 6's pheromone-greedy ant; its weights are only computed when Eq. 5 uses L_pn
        # (otherwise it reuses the colony's weights and its length is not used)
        greedy_tau = jax.lax.cond(
            p.use_adaptive_weight,
            lambda: choice_weights(state.tau, log_eta, _f(1.0), _f(0.0)),
            lambda: weights)
        stacked = jnp.concatenate([weights, greedy_tau], axis=0)  # (2n, n)
        starts = jnp.concatenate(
            [jax.random.randint(k_start, (m,), 0, n, jnp.int32), jnp.zeros((1,), jnp.int32)]
        )
        offset = jnp.concatenate([jnp.zeros((m,), jnp.int32), jnp.full((1,), n, jnp.int32)])
        q0 = jnp.concatenate([jnp.full((m,), p.q0), jnp.ones((1,))])
        cands = problem.neighbors if self.candidate_lists else None
        # sparse: the best tour so far (the first tour before one): what the fallback follows,
        # what focused ants change and search from, and what merging improves on
        ref = jnp.where(jnp.isfinite(state.best_cost), state.best_solution,
                        state.first_tour) if sparse else None
        if sparse and self.reference == "iteration":  # a key of its own: the split is kept
            coin = jax.random.uniform(jax.random.fold_in(key, 5)) < self.reference_best_prob
            ref = jnp.where(coin, ref, state.source)

        def build(chaos_factor):
            if sparse:
                if self.construction != "ants":
                    return construct_tours_moves(
                        k_build, stacked, problem.neighbors, ref, self.max_new_edges, m + 1,
                        q0, offset, chaos_factor,
                        kind="or3opt" if self.construction == "moves-or3opt" else "2opt",
                        new_only=self.construction == "moves-new", plan=self.moves_plan)
                return construct_tours_sparse(k_build, stacked, problem.neighbors, starts, ref,
                                              q0, offset, chaos_factor, self.max_new_edges,
                                              self._sparse_plan())
            return construct_tours(k_build, stacked, starts, q0, offset, chaos_factor, cands,
                                   self.construction_fallback)

        # without chaos the factor is all ones: skip its per-step gathers and products
        built = jax.lax.cond(p.use_chaos, lambda: build(factor), lambda: build(None))
        tours, pher_tour = built[:m], built[m:]
        l_pn = tour_lengths(dist, pher_tour)[0]
        if self._seeded(problem):  # the first iteration's ant 0 takes the first tour
            tours = tours.at[0].set(jnp.where(jnp.isfinite(state.best_cost), tours[0],
                                              state.first_tour))

        tours = self._genetic(k_cx, k_mut, tours, state, dist)
        focus = None
        if sparse and self.max_new_edges is not None:  # search from the changed edges only
            from eaco_jax.ops.local_search import changed_cities

            focus = changed_cities(tours, ref)
        tours = self._local_search(tours, problem, k_ls[0] if k_ls else None, focus)
        if sparse and self.merge_ants is not None:
            from eaco_jax.ops.tour_merge import merge_improvements

            merged, _, count, worst = merge_improvements(ref, tours, dist, self.merge_ants)
            tours = jnp.where(count >= 2, tours.at[worst].set(merged), tours)
        return tours, state.replace(chaos=x, pheromone_tour_length=l_pn)

    def _genetic(
        self, k_cx: Array, k_mut: Array, tours: Array, state: GraphState, dist: Array
    ) -> Array:
        """Crossover with the best-so-far tour and mutation, at self-adaptive rates."""
        p = state.params
        m = tours.shape[0]
        if self.crossover == "none" and self.mutation == "none":
            return tours
        from eaco_jax.ops import tour_ops

        lengths = tour_lengths(dist, tours)
        lo, mean = jnp.min(lengths), jnp.mean(lengths)
        # Srinivas & Patnaik style: better-than-average ants get rates scaled by how far they
        # are from the iteration best (the best gets 0), worse ones the full rate.
        scale = jnp.where(
            lengths <= mean, (lengths - lo) / jnp.maximum(mean - lo, 1e-9), 1.0
        )
        scale = jnp.where(p.use_adaptive_rates, scale, 1.0)
        rate_c, rate_m = p.p_crossover * scale, p.p_mutation * scale

        kc1, kc2 = jax.random.split(k_cx)
        km1, km2 = jax.random.split(k_mut)
        if self.crossover != "none":
            op = tour_ops.erx if self.crossover == "erx" else tour_ops.pmx
            have_best = jnp.isfinite(state.best_cost)
            partner = jnp.where(
                have_best, jnp.broadcast_to(state.best_solution, tours.shape),
                jnp.roll(tours, 1, axis=0),
            )
            children = jax.vmap(op)(jax.random.split(kc1, m), tours, partner)
            do = jax.random.uniform(kc2, (m,)) < rate_c
            tours = jnp.where(do[:, None], children, tours)
        if self.mutation != "none":
            op = tour_ops.inversion_mutation if self.mutation == "inversion" else (
                tour_ops.swap_mutation)
            mutants = jax.vmap(op)(jax.random.split(km1, m), tours)
            do = jax.random.uniform(km2, (m,)) < rate_m
            tours = jnp.where(do[:, None], mutants, tours)
        return tours

    def _local_search(self, tours: Array, problem: Any, key: Array | None = None,
                      focus: Array | None = None) -> Array:
        """2-opt ("2opt": batched best improvement; "or-2opt": the same with Or-opt moves
        competing; "2opt-dlb": ACOTSP's first improvement with don't-look bits; "2opt+oropt":
        the latter plus Or-opt; these two run as native code on a CPU, with the same tours),
        on every ant or on the ``ls_best_k`` shortest tours only. ``focus`` ``(m, n)``: the
        don't-look-bit searches start from these cities only (Focused ACO's construction:
        the ends of the edges an ant changed); the batched searches too when
        ``ls_focus_width`` is set, else they scan every city."""
        if self.local_search == "none":
            return tours
        from eaco_jax.ops import local_search

        dist = local_search.as_distances(problem.dist)
        neighbors = problem.neighbors
        if self.ls_neighbors is not None and neighbors is not None:
            neighbors = neighbors[:, : self.ls_neighbors]
        batched = self.local_search in ("2opt", "or-2opt")
        if batched:
            def improve(t, a=None):
                return local_search.two_opt(t, dist, neighbors, self.max_ls_moves,
                                            moves_per_step=self.ls_moves_per_step,
                                            or_opt=self.local_search == "or-2opt", active=a,
                                            focus_width=self.ls_focus_width or 1,
                                            compact=None if a is None else self.ls_compact,
                                            loop=self.ls_loop,
                                            acceptance=self.ls_acceptance)
        else:
            def improve(t, a=None):
                return local_search.dlb_local_search(
                    key, t, dist, neighbors, self.max_ls_moves,
                    or_opt=self.local_search == "2opt+oropt", active=a)
        extra = () if focus is None or (batched and self.ls_focus_width is None) else (focus,)
        if self.ls_best_k is None or self.ls_best_k >= tours.shape[0]:
            return improve(tours, *extra)
        return local_search.best_k(tours, tour_lengths(dist, tours), self.ls_best_k, improve,
                                   *extra)

    # ------------------------------------------------------------------ tell
    def _tell(
        self, state: GraphState, solutions: Array, fitness: Array, problem: Any
    ) -> tuple[GraphState, dict[str, Array]]:
        p = state.params
        n = state.tau.shape[0]
        cands = problem.neighbors if is_sparse(problem) else None  # (n, k) trails on them
        lengths = fitness.astype(jnp.float32)
        previous_iter_best = state.iter_best_cost
        previous_best = state.best_cost
        state = record_best(state, solutions, lengths)
        i_best = jnp.argmin(lengths)
        # MMAS restart-best: the best tour since the last trail restart
        rb_improved = lengths[i_best] < state.restart_best_cost
        rb_solution = jnp.where(rb_improved, solutions[i_best], state.restart_best_solution)
        rb_cost = jnp.where(rb_improved, lengths[i_best], state.restart_best_cost)
        improved = jnp.where(p.use_restart_best, rb_improved,
                             state.best_cost < previous_best)
        since = jnp.where(improved, 0, state.since_improvement + 1)

        rho_t = jnp.where(
            p.use_evaporation_schedule,
            pheromone.evaporation_schedule(
                p.rho, since.astype(jnp.float32), p.stagnation_window, p.evaporation_slowdown
            ),
            p.rho,
        )
        alpha_g = jnp.where(p.use_evaporation_schedule, p.alpha_g * rho_t / p.rho, p.alpha_g)

        tau = state.tau
        # Eq. 68-70
        # switched-off rules are skipped (lax.cond; a select under vmap over switches)
        tau = jax.lax.cond(
            p.use_local_update,
            lambda t: pheromone.local_update(t, solutions, lengths, rho_t, p.q, cands),
            lambda t: t, tau,
        )
        # Eq. 71 on the best-so-far tour (every gb_every iterations) or the iteration best
        use_gb = (state.iteration % jnp.maximum(p.gb_every, 1.0).astype(jnp.int32)) == 0
        gb_solution = jnp.where(p.use_restart_best, rb_solution, state.best_solution)
        gb_cost = jnp.where(p.use_restart_best, rb_cost, state.best_cost)
        target = jnp.where(use_gb, gb_solution, solutions[i_best])
        target_len = jnp.where(use_gb, gb_cost, lengths[i_best])
        tau = jax.lax.cond(
            p.use_global_update,
            lambda t: pheromone.global_update(t, target, target_len, alpha_g, cands),
            lambda t: t, tau,
        )
        # Eq. 3-5 deposit weights, Eq. 73-74 elitist reinforcement
        mask = jnp.where(
            p.use_deposit_condition,
            pheromone.elitist_deposit_mask(lengths, previous_iter_best),
            True,
        ).astype(jnp.float32)
        weight_n = pheromone.adaptive_weight(lengths, state.pheromone_tour_length)
        weights = mask * jnp.where(p.use_adaptive_weight, 2.0 * weight_n, 1.0)
        tau = jax.lax.cond(
            p.use_elitist,
            lambda t: pheromone.elitist_update(
                t, solutions, lengths, weights / self.num_ants, state.best_solution,
                state.best_cost, rho_t, p.q, p.sigma, cands,
            ),
            lambda t: t, tau,
        )
        # Eq. 7 and MMAS restart
        tau_max, tau_min = self._bounds(p, state.best_cost, n)
        tau = pheromone.clamp(tau, tau_min, tau_max)
        branching = pheromone.branching_factor(tau, None if cands is not None
                                               else problem.neighbors)
        converged = (p.restart_branching <= 0) | (branching < p.restart_branching)
        restart = p.use_restart & (since >= p.restart_after) & converged
        reset_to = self._bounds(p.replace(use_bounds=jnp.bool_(True)), state.best_cost, n)[0]
        tau = pheromone.reset(tau, reset_to, restart)
        since = jnp.where(restart, 0, since)

        from eaco_jax.ops.diversity import edge_diversity

        diversity = (edge_diversity(solutions) if cands is None
                     else pheromone.candidate_edge_diversity(solutions, cands))
        state = state.replace(
            tau=tau,
            iter_best_cost=jnp.min(lengths).astype(jnp.float32),
            since_improvement=since,
            restart_best_solution=rb_solution,
            restart_best_cost=jnp.where(restart, jnp.inf, rb_cost).astype(jnp.float32),
            restarts=state.restarts + restart.astype(jnp.int32),
        )
        if isinstance(state, SparseGraphState):  # the next iteration's "iteration" reference
            state = state.replace(source=solutions[i_best])
        metrics = {
            "diversity": jnp.clip(diversity, 0.0, 1.0).astype(jnp.float32),
            "rho_t": rho_t.astype(jnp.float32),
            "adaptive_rho": jnp.mean(weight_n).astype(jnp.float32),
            "pheromone_tour_length": state.pheromone_tour_length,
            "restarts": state.restarts,
            "branching_factor": branching,
            "tau_min": tau_min,
            "tau_max": tau_max,
        }
        return state, metrics

    # ------------------------------------------------------------------ islands (migration)
    def immigrate(
        self, state: GraphState, solutions: Array, fitness: Array, key: Array,
        replace: str = "worst",
    ) -> GraphState:
        """Migrant tours enter the best-so-far and MMAS restart-best records, the tours the
        global update deposits on and crossover pairs with (there is no population, so
        ``replace`` has nothing to choose); an improvement resets the restart counter."""
        p = state.params
        lengths = fitness.astype(jnp.float32)
        previous_best = state.best_cost
        state = adopt_best(state, solutions, lengths)
        i = jnp.argmin(lengths)
        rb_better = lengths[i] < state.restart_best_cost
        improved = jnp.where(p.use_restart_best, rb_better, state.best_cost < previous_best)
        return state.replace(
            restart_best_solution=jnp.where(rb_better, solutions[i], state.restart_best_solution),
            restart_best_cost=jnp.where(rb_better, lengths[i], state.restart_best_cost),
            since_improvement=jnp.where(improved, 0, state.since_improvement),
        )
