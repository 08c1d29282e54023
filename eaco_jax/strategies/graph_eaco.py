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

Every mechanism has a 0/1 switch in :class:`GraphParams` (traced, so ablations and sweeps vmap).
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
    assumes (k + 1) / 2 choices per step on k candidates (``branching``). Measured against the
    earlier settings (beta 5, restart after 250 iterations without a new best-so-far,
    n / 2 - 1 choices), this finds the eil51 optimum in 10 s where those stopped at 427.
  * beta = 2 (ACOTSP's default; Table 4's 5 converges to worse tours in our runs).
  * Q = 1 instead of 100: the same units (1/length) as Eq. 71, see :mod:`eaco_jax.ops.pheromone`.
  * q0 = 0 (Table 3's best q0 = 0.8 is for the constrained problem G1; it makes TSP colonies
    converge prematurely); local update, elitist reinforcement, the Eq. 3-4 condition, the
    adaptive weight, chaos and the evaporation schedule are implemented but off by default
    (each measured in ``experiments/``); crossover/mutation are on with the paper's p_c = 0.6,
    p_m = 0.5 under self-adaptive scaling when 2-opt is on, and off without it (``"auto"``).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.ops import chaos, pheromone
from eaco_jax.ops.construction import (
    choice_weights,
    construct_tours,
    heuristic_log_eta,
    tour_lengths,
)
from eaco_jax.problems.base import ProblemError
from eaco_jax.problems.tsp import DEFAULT_NEIGHBORS
from eaco_jax.strategies.base import State, Strategy, base_fields, record_best

Array = jax.Array

LOCAL_SEARCHES = ("2opt", "2opt-dlb", "2opt+oropt", "none")
CROSSOVERS = ("erx", "pmx", "none")
MUTATIONS = ("inversion", "swap", "none")


@struct.dataclass
class GraphParams:
    """Traced hyper-parameters. Switches are 0.0 (off) / 1.0 (on)."""

    alpha: Array  # pheromone weight in Eq. 2
    beta: Array  # heuristic weight in Eq. 2
    rho: Array  # evaporation rate (local update, elitist update)
    q0: Array  # pseudo-random proportional rule
    alpha_g: Array  # global evaporation of Eq. 71
    sigma: Array  # number of elitist ants, Eq. 74
    q: Array  # deposit factor Q
    p_best: Array  # MMAS: probability of rebuilding the best tour at the limits
    branching: Array  # MMAS tau_min: average choices per step (0: n/2 - 1)
    chaos_strength: Array  # selection factor in [1 - s, 1 + s]
    p_crossover: Array
    p_mutation: Array
    restart_after: Array  # iterations without improvement before a trail restart
    restart_branching: Array  # ... and only once the trails' lambda-branching factor is
    # below this (converged; ACOTSP's 1.00001); 0: no convergence test
    use_restart_best: Array  # MMAS: deposit and count stagnation on the best tour since the
    # last restart instead of the best-so-far tour
    gb_every: Array  # global update uses the best-so-far tour every gb_every iterations
    stagnation_window: Array  # evaporation schedule: iterations to full slow-down
    evaporation_slowdown: Array  # evaporation schedule strength in [0, 1)
    use_local_update: Array
    use_global_update: Array
    use_elitist: Array
    use_deposit_condition: Array
    use_adaptive_weight: Array
    use_bounds: Array
    use_chaos: Array
    use_evaporation_schedule: Array
    use_restart: Array
    use_adaptive_rates: Array
    init_at_tau_max: Array


@struct.dataclass
class GraphState(State):
    tau: Array  # (n, n) pheromone
    log_eta: Array  # (n, n) heuristic cache log(1/d)
    dist: Array  # (n, n)
    neighbors: Array  # (n, k) candidate lists for construction and local search
    chaos: Array  # (m, n) logistic-map variables
    tau_min: Array
    tau_max: Array
    rho_t: Array  # evaporation rate in force (stagnation schedule)
    adaptive_rho: Array  # mean Eq. 5 weight of the last iteration
    pheromone_tour_length: Array  # L_pn of the last iteration (Eq. 6 tour; with the adaptive
    # weight off, the greedy tour on the colony weights, which nothing uses)
    p_crossover_t: Array  # mean self-adaptive crossover rate of the last iteration
    p_mutation_t: Array
    since_improvement: Array  # restart counter
    restart_best_solution: Array  # best tour since the last restart
    restart_best_cost: Array
    branching_factor: Array  # lambda-branching factor of the trails (lambda = 0.05)
    restarts: Array
    nn_length: Array


def _f(x: float) -> Array:
    return jnp.asarray(x, jnp.float32)


@dataclasses.dataclass(frozen=True)
class GraphEACO(Strategy):
    """EACO colony for graph problems (TSP). See the module docstring for the algorithm."""

    num_ants: int = 40
    local_search: str = "2opt"
    #: "auto": ERX / inversion with local search, "none" without (measured: without 2-opt
    #: they cost 3x the time per iteration and lower the quality reached in a fixed time)
    crossover: str = "auto"
    mutation: str = "auto"
    #: cap on 2-opt improving moves per tour per iteration (None: run to a local optimum)
    max_ls_moves: int | None = None
    #: local search on the ls_best_k shortest tours of each iteration only (None: all ants)
    ls_best_k: int | None = None
    #: build tours on the problem's nearest-neighbour candidate lists (see construction.py)
    candidate_lists: bool = True
    #: how construction's whole-row fallback runs ("auto", "lazy", "dense", "backup"; see
    #: construction.construct_tours): a cost choice only, every plan builds the same tours
    construction_fallback: str = "auto"
    problem_kind: ClassVar[str] = "graph"

    def __post_init__(self) -> None:
        with_ls = self.local_search != "none"
        for name, on in (("crossover", "erx"), ("mutation", "inversion")):
            if getattr(self, name) == "auto":
                object.__setattr__(self, name, on if with_ls else "none")
        if self.num_ants < 1:
            raise ValueError(f"num_ants must be >= 1, got {self.num_ants}")
        if self.ls_best_k is not None and self.ls_best_k < 1:
            raise ValueError(f"ls_best_k must be >= 1 or None, got {self.ls_best_k}")
        for name, value, allowed in (
            ("local_search", self.local_search, LOCAL_SEARCHES),
            ("crossover", self.crossover, CROSSOVERS),
            ("mutation", self.mutation, MUTATIONS),
        ):
            if value not in allowed:
                raise ValueError(f"{name}={value!r} is not one of {allowed}")

    # ------------------------------------------------------------------ params
    def default_params(self, problem: Any = None) -> GraphParams:
        with_ls = self.local_search != "none"
        k = getattr(problem, "neighbors", None)
        k = DEFAULT_NEIGHBORS if k is None else int(k.shape[1])
        return GraphParams(
            alpha=_f(1.0),
            beta=_f(2.0),
            rho=_f(0.2 if with_ls else 0.02),
            q0=_f(0.0),
            alpha_g=_f(0.2 if with_ls else 0.02),
            sigma=_f(6.0),
            q=_f(1.0),
            p_best=_f(0.05),
            branching=_f(0.0 if with_ls else float((k + 1) // 2)),
            chaos_strength=_f(0.1),
            p_crossover=_f(0.6),
            p_mutation=_f(0.5),
            restart_after=_f(50.0 if with_ls else 250.0),
            restart_branching=_f(0.0 if with_ls else 1.00001),
            use_restart_best=_f(0.0 if with_ls else 1.0),
            gb_every=_f(3.0 if with_ls else 25.0),
            stagnation_window=_f(50.0),
            evaporation_slowdown=_f(0.5),
            use_local_update=_f(0.0),
            use_global_update=_f(1.0),
            use_elitist=_f(0.0),
            use_deposit_condition=_f(0.0),
            use_adaptive_weight=_f(0.0),
            use_bounds=_f(1.0),
            use_chaos=_f(0.0),
            use_evaporation_schedule=_f(0.0),
            use_restart=_f(1.0),
            use_adaptive_rates=_f(1.0),
            init_at_tau_max=_f(1.0),
        )

    # ------------------------------------------------------------------ init
    def _init(self, key: Array, problem: Any, params: GraphParams) -> GraphState:
        dist = jnp.asarray(problem.dist, jnp.float32)
        n = dist.shape[0]
        if dist.ndim != 2 or dist.shape[1] != n or n < 3:
            raise ProblemError(
                f"graph problem needs an (n, n) distance matrix, n >= 3; got {dist.shape}")
        neighbors = jnp.asarray(problem.neighbors, jnp.int32)
        log_eta = heuristic_log_eta(dist)
        k_chaos, key = jax.random.split(key)
        # nearest-neighbour tour from node 0: greedy on eta alone
        nn_weights = choice_weights(jnp.ones_like(dist), log_eta, _f(0.0), _f(1.0))
        nn_tour = construct_tours(k_chaos, nn_weights, jnp.zeros((1,), jnp.int32), q0=1.0)
        nn_length = tour_lengths(dist, nn_tour)[0]
        tau_max, tau_min = self._bounds(params, nn_length, n)
        tau0 = jnp.where(
            params.init_at_tau_max > 0.5, tau_max, pheromone.initial_tau(n, nn_length)
        )
        tau = jnp.full((n, n), tau0, jnp.float32)
        return GraphState(
            **base_fields(key, params, jnp.arange(n, dtype=jnp.int32)),
            tau=tau,
            log_eta=log_eta,
            dist=dist,
            neighbors=neighbors,
            chaos=chaos.logistic_init(k_chaos, (self.num_ants, n)),
            tau_min=tau_min,
            tau_max=tau_max,
            rho_t=params.rho,
            adaptive_rho=_f(0.5),
            pheromone_tour_length=nn_length,
            p_crossover_t=params.p_crossover,
            p_mutation_t=params.p_mutation,
            since_improvement=jnp.zeros((), jnp.int32),
            restart_best_solution=jnp.arange(n, dtype=jnp.int32),
            restart_best_cost=jnp.asarray(jnp.inf, jnp.float32),
            branching_factor=pheromone.branching_factor(tau, neighbors),
            restarts=jnp.zeros((), jnp.int32),
            nn_length=nn_length,
        )

    def _bounds(self, p: GraphParams, best_length: Array, n: int) -> tuple[Array, Array]:
        """MMAS limits for the rules that are on (tau_max = steady state of the best tour)."""
        scale = p.use_global_update + p.use_elitist * p.q * (p.sigma + 1.0)
        scale = jnp.maximum(scale, 1.0)
        tau_max, tau_min = pheromone.mmas_bounds(best_length, n, p.p_best, scale, p.branching)
        on = p.use_bounds > 0.5
        return jnp.where(on, tau_max, jnp.inf), jnp.where(on, tau_min, 1e-30)

    # ------------------------------------------------------------------ ask
    def _ask(self, key: Array, state: GraphState) -> tuple[Array, GraphState]:
        p = state.params
        m, n = self.num_ants, state.tau.shape[0]
        # the ACOTSP-style searches draw a random city order: a fifth key (the other kinds keep
        # the four-way split, so their tours are unchanged)
        dlb = self.local_search in ("2opt-dlb", "2opt+oropt")
        k_start, k_build, k_cx, k_mut, *k_ls = jax.random.split(key, 5 if dlb else 4)

        x = chaos.logistic_step(state.chaos)
        factor = jnp.where(p.use_chaos > 0.5, chaos.perturbation(x, p.chaos_strength), 1.0)
        factor = jnp.concatenate([factor, jnp.ones((1, n), jnp.float32)], axis=0)

        weights = choice_weights(state.tau, state.log_eta, p.alpha, p.beta)
        # Eq. 6's pheromone-greedy ant; its weights are only computed when Eq. 5 uses L_pn
        # (otherwise it reuses the colony's weights and its length is not used)
        greedy_tau = jax.lax.cond(
            p.use_adaptive_weight > 0.5,
            lambda: choice_weights(state.tau, state.log_eta, _f(1.0), _f(0.0)),
            lambda: weights)
        stacked = jnp.concatenate([weights, greedy_tau], axis=0)  # (2n, n)
        starts = jnp.concatenate(
            [jax.random.randint(k_start, (m,), 0, n, jnp.int32), jnp.zeros((1,), jnp.int32)]
        )
        offset = jnp.concatenate([jnp.zeros((m,), jnp.int32), jnp.full((1,), n, jnp.int32)])
        q0 = jnp.concatenate([jnp.full((m,), p.q0), jnp.ones((1,))])
        cands = state.neighbors if self.candidate_lists else None

        def build(chaos_factor):
            return construct_tours(k_build, stacked, starts, q0, offset, chaos_factor, cands,
                                   self.construction_fallback)

        # without chaos the factor is all ones: skip its per-step gathers and products
        built = jax.lax.cond(p.use_chaos > 0.5, lambda: build(factor), lambda: build(None))
        tours, pher_tour = built[:m], built[m:]
        l_pn = tour_lengths(state.dist, pher_tour)[0]

        tours, pc, pm = self._genetic(k_cx, k_mut, tours, state)
        tours = self._local_search(tours, state, k_ls[0] if k_ls else None)
        return tours, state.replace(
            chaos=x,
            pheromone_tour_length=l_pn,
            p_crossover_t=pc,
            p_mutation_t=pm,
        )

    def _genetic(self, k_cx: Array, k_mut: Array, tours: Array, state: GraphState):
        """Crossover with the best-so-far tour and mutation, at self-adaptive rates."""
        p = state.params
        m = tours.shape[0]
        if self.crossover == "none" and self.mutation == "none":
            return tours, _f(0.0), _f(0.0)
        from eaco_jax.ops import tour_ops

        lengths = tour_lengths(state.dist, tours)
        lo, mean = jnp.min(lengths), jnp.mean(lengths)
        # Srinivas & Patnaik style: better-than-average ants get rates scaled by how far they
        # are from the iteration best (the best gets 0), worse ones the full rate.
        scale = jnp.where(
            lengths <= mean, (lengths - lo) / jnp.maximum(mean - lo, 1e-9), 1.0
        )
        scale = jnp.where(p.use_adaptive_rates > 0.5, scale, 1.0)
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
        pc = rate_c.mean() if self.crossover != "none" else _f(0.0)
        pm = rate_m.mean() if self.mutation != "none" else _f(0.0)
        return tours, pc, pm

    def _local_search(self, tours: Array, state: GraphState, key: Array | None = None) -> Array:
        """2-opt ("2opt": batched best improvement; "2opt-dlb": ACOTSP's first improvement with
        don't-look bits; "2opt+oropt": the latter plus Or-opt), on every ant or on the
        ``ls_best_k`` shortest tours only."""
        if self.local_search == "none":
            return tours
        from eaco_jax.ops import local_search

        if self.local_search == "2opt":
            def improve(t):
                return local_search.two_opt(t, state.dist, state.neighbors, self.max_ls_moves)
        else:
            def improve(t):
                return local_search.dlb_local_search(
                    key, t, state.dist, state.neighbors, self.max_ls_moves,
                    or_opt=self.local_search == "2opt+oropt")
        if self.ls_best_k is None or self.ls_best_k >= tours.shape[0]:
            return improve(tours)
        return local_search.best_k(tours, tour_lengths(state.dist, tours), self.ls_best_k,
                                   improve)

    # ------------------------------------------------------------------ tell
    def _tell(self, state: GraphState, solutions: Array, fitness: Array) -> GraphState:
        p = state.params
        n = state.tau.shape[0]
        lengths = fitness.astype(jnp.float32)
        previous_iter_best = state.iter_best_cost
        previous_best = state.best_cost
        state = record_best(state, solutions, lengths)
        i_best = jnp.argmin(lengths)
        on = lambda s: s > 0.5  # noqa: E731
        # MMAS restart-best: the best tour since the last trail restart
        rb_improved = lengths[i_best] < state.restart_best_cost
        rb_solution = jnp.where(rb_improved, solutions[i_best], state.restart_best_solution)
        rb_cost = jnp.where(rb_improved, lengths[i_best], state.restart_best_cost)
        improved = jnp.where(on(p.use_restart_best), rb_improved,
                             state.best_cost < previous_best)
        since = jnp.where(improved, 0, state.since_improvement + 1)

        rho_t = jnp.where(
            on(p.use_evaporation_schedule),
            pheromone.evaporation_schedule(
                p.rho, since.astype(jnp.float32), p.stagnation_window, p.evaporation_slowdown
            ),
            p.rho,
        )
        alpha_g = jnp.where(on(p.use_evaporation_schedule), p.alpha_g * rho_t / p.rho, p.alpha_g)

        tau = state.tau
        # Eq. 68-70
        # switched-off rules are skipped (lax.cond; a select under vmap over switches)
        tau = jax.lax.cond(
            on(p.use_local_update),
            lambda t: pheromone.local_update(t, solutions, lengths, rho_t, p.q),
            lambda t: t, tau,
        )
        # Eq. 71 on the best-so-far tour (every gb_every iterations) or the iteration best
        use_gb = (state.iteration % jnp.maximum(p.gb_every, 1.0).astype(jnp.int32)) == 0
        gb_solution = jnp.where(on(p.use_restart_best), rb_solution, state.best_solution)
        gb_cost = jnp.where(on(p.use_restart_best), rb_cost, state.best_cost)
        target = jnp.where(use_gb, gb_solution, solutions[i_best])
        target_len = jnp.where(use_gb, gb_cost, lengths[i_best])
        tau = jax.lax.cond(
            on(p.use_global_update),
            lambda t: pheromone.global_update(t, target, target_len, alpha_g),
            lambda t: t, tau,
        )
        # Eq. 3-5 deposit weights, Eq. 73-74 elitist reinforcement
        mask = jnp.where(
            on(p.use_deposit_condition),
            pheromone.elitist_deposit_mask(lengths, previous_iter_best),
            True,
        ).astype(jnp.float32)
        weight_n = pheromone.adaptive_weight(lengths, state.pheromone_tour_length)
        weights = mask * jnp.where(on(p.use_adaptive_weight), 2.0 * weight_n, 1.0)
        tau = jax.lax.cond(
            on(p.use_elitist),
            lambda t: pheromone.elitist_update(
                t, solutions, lengths, weights / self.num_ants, state.best_solution,
                state.best_cost, rho_t, p.q, p.sigma,
            ),
            lambda t: t, tau,
        )
        # Eq. 7 and MMAS restart
        tau_max, tau_min = self._bounds(p, state.best_cost, n)
        tau = pheromone.clamp(tau, tau_min, tau_max)
        branching = pheromone.branching_factor(tau, state.neighbors)
        converged = (p.restart_branching <= 0) | (branching < p.restart_branching)
        restart = on(p.use_restart) & (since >= p.restart_after) & converged
        tau = pheromone.reset(tau, tau_max, restart)
        since = jnp.where(restart, 0, since)

        from eaco_jax.ops.diversity import edge_diversity

        return state.replace(
            tau=tau,
            tau_min=tau_min,
            tau_max=tau_max,
            rho_t=rho_t.astype(jnp.float32),
            adaptive_rho=jnp.mean(weight_n).astype(jnp.float32),
            since_improvement=since,
            restart_best_solution=rb_solution,
            restart_best_cost=jnp.where(restart, jnp.inf, rb_cost).astype(jnp.float32),
            branching_factor=branching,
            restarts=state.restarts + restart.astype(jnp.int32),
            diversity=jnp.clip(edge_diversity(solutions), 0.0, 1.0).astype(jnp.float32),
        )

    def stats(self, state: GraphState) -> dict[str, Array]:
        out = super().stats(state)
        out.update(
            rho_t=state.rho_t,
            adaptive_rho=state.adaptive_rho,
            pheromone_tour_length=state.pheromone_tour_length,
            p_crossover=state.p_crossover_t,
            p_mutation=state.p_mutation_t,
            restarts=state.restarts,
            branching_factor=state.branching_factor,
        )
        return out
