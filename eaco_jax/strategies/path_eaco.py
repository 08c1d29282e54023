"""EACO for start-to-goal path planning on a visibility graph (paper §5, Figs. 4-7).

It solves any ``kind = "path"`` problem: shortest length
(:class:`~eaco_jax.problems.path_planning.PathPlanning`) or least walking time through a scene
(:class:`~eaco_jax.problems.scenes.ScenePath`); it reads the problem's ``step_cost`` and
``goal_cost``.

The colony machinery is the graph colony's: random-proportional choice (Eq. 2) with the q0
rule, logistic-map chaos on the choice weights, elitist reinforcement (Eq. 73-74) restricted by
the elitist-only deposit condition (Eq. 3-4) and weighted adaptively (Eq. 5), MAX-MIN bounds
(Eq. 7) and a stagnation-driven evaporation schedule - all from :mod:`eaco_jax.ops.pheromone`.
What differs is the walk: an ant starts at the start node, may only take visible edges, stops
at the goal, and is dead (cost +inf) if it gets stuck. The heuristic is goal-directed,
eta_ij = 1 / (c_ij + h_j) (edge cost plus a lower bound on the cost left to the goal), so ants
prefer cheap edges that head for the goal.

Genetic operators on paths: *common-node crossover* (the child follows parent A to a node both
parents visit, then parent B to the goal) with probability ``p_crossover``, and *shortcut*
(string pulling: from each node jump to the furthest later node of the path joined to it by an
edge no dearer than the path between them), the path analogue of 2-opt, applied to every ant
when ``use_shortcut`` is on.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar  # noqa: F401  (Any: the State annotations, for pdoc)

import jax
import jax.numpy as jnp
from flax import struct

from eaco_jax.ops import chaos, pheromone
from eaco_jax.ops.construction import choice_weights
from eaco_jax.ops.path_ops import common_node_crossover, path_diversity, shortcut
from eaco_jax.problems.path_planning import GOAL, START, PathPlanning
from eaco_jax.strategies.base import (
    BOOL,
    NONNEG,
    POSITIVE,
    UNIT,
    Range,
    State,
    Strategy,
    as_params,
    base_fields,
    record_best,
)

Array = jax.Array


@struct.dataclass
class PathParams:
    """Traced hyper-parameters (names shared with :class:`GraphParams` where the idea is)."""

    alpha: Array = 1.0  # pheromone exponent (Eq. 2)
    beta: Array = 3.0  # heuristic exponent (Eq. 2)
    rho: Array = 0.1  # evaporation rate
    q0: Array = 0.2  # probability of the greedy choice
    q: Array = 1.0  # deposit factor Q
    sigma: Array = 4.0  # elitist ants (Eq. 74)
    p_best: Array = 0.05  # MAX-MIN: probability of rebuilding the best path at the bounds
    p_crossover: Array = 0.3  # common-node crossover probability per ant
    chaos_strength: Array = 0.1  # logistic-map perturbation of the choice weights
    stagnation_window: Array = 30.0  # iterations without improvement before evaporation slows
    evaporation_slowdown: Array = 0.5  # how much it slows (0 = fixed rho)
    use_chaos: Array = True
    use_shortcut: Array = True  # string-pulling local search on every ant
    use_adaptive_weight: Array = True  # Eq. 5 adaptive deposit weights (else equal weights)

    #: documented ranges, checked on the host before a run (concrete values only)
    RANGES: ClassVar[dict[str, Range]] = {
        "alpha": Range(0.0, 10.0), "beta": Range(0.0, 20.0), "rho": Range(0.0, 1.0, True),
        "q0": UNIT, "q": POSITIVE, "sigma": NONNEG, "p_best": Range(0.0, 1.0, True, True),
        "p_crossover": UNIT, "chaos_strength": Range(0.0, 1.0, open_high=True),
        "stagnation_window": POSITIVE, "evaporation_slowdown": Range(0.0, 1.0, open_high=True),
        "use_chaos": BOOL, "use_shortcut": BOOL, "use_adaptive_weight": BOOL,
    }


@struct.dataclass
class PathState(State):
    tau: Array  # (n, n) pheromone
    chaos_x: Array  # (m,) logistic-map variables


def path_log_eta(problem: PathPlanning) -> Array:
    """Goal-directed heuristic log(1 / (c_ij + h_j)), -inf where blocked: ``c`` the problem's
    edge cost (length or walking time), ``h`` its lower bound on the cost left to the goal."""
    cost = problem.step_cost.astype(jnp.float32)
    free = jnp.isfinite(cost)
    log_eta = jnp.where(free, -jnp.log(cost + problem.goal_cost[None, :] + 1e-6), -jnp.inf)
    return log_eta.astype(jnp.float32)


@dataclasses.dataclass(frozen=True)
class PathEACO(Strategy):
    """Path-planning colony; ``num_ants`` walks per iteration."""

    num_ants: int = 32
    problem_kind: ClassVar[str] = "path"

    def default_params(self, problem: PathPlanning | None = None) -> PathParams:
        return as_params(PathParams())

    def inactive_params(self, params: PathParams) -> dict[str, str]:
        """Fields without effect under these switches -> the switch that makes them act."""
        dead: dict[str, str] = {}
        if not bool(jnp.all(jnp.asarray(params.use_chaos))):
            dead["chaos_strength"] = "use_chaos"
        if not bool(jnp.all(jnp.asarray(params.evaporation_slowdown) > 0)):
            dead["stagnation_window"] = "evaporation_slowdown > 0"
        return dead

    def _init(self, key: Array, problem: PathPlanning, params: PathParams) -> PathState:
        n = problem.n
        tau0 = 1.0 / (n * jnp.sum(problem.goal_cost[START]))  # 1/(n * straight-line cost)
        key, k_chaos = jax.random.split(key)
        template = jnp.full((n,), GOAL, jnp.int32).at[0].set(START)
        return PathState(
            **base_fields(key, params, template),
            tau=jnp.full((n, n), tau0, jnp.float32),
            chaos_x=chaos.logistic_init(k_chaos, (self.num_ants,)),
        )

    # ------------------------------------------------------------------ construction
    def _walk(self, key: Array, state: PathState, problem: PathPlanning) -> Array:
        """(m, n) node sequences from START, stopping at GOAL (stuck ants stay put)."""
        p = state.params
        m, n = self.num_ants, state.tau.shape[0]
        w = choice_weights(state.tau, path_log_eta(problem), p.alpha, p.beta)
        factor = jnp.where(p.use_chaos, chaos.perturbation(state.chaos_x, p.chaos_strength),
                           1.0)[:, None]
        rows = jnp.arange(m)

        def step(carry, k):
            cur, visited, done = carry
            wc = jnp.where(visited, 0.0, w[cur] * factor)
            total = wc.sum(axis=1)
            greedy = jnp.argmax(wc, axis=1)
            u = jax.random.uniform(k, (2, m))
            sampled = jnp.argmax(jnp.cumsum(wc, axis=1) > (u[0] * total)[:, None], axis=1)
            choice = jnp.where(u[1] < p.q0, greedy, sampled)
            nxt = jnp.where(done | (total <= 0), cur, choice).astype(jnp.int32)
            visited = visited.at[rows, nxt].set(True)
            return (nxt, visited, done | (nxt == GOAL)), nxt

        start = jnp.full((m,), START, jnp.int32)
        visited = jnp.zeros((m, n), bool).at[:, START].set(True)
        init = (start, visited, jnp.zeros((m,), bool))
        _, seq = jax.lax.scan(step, init, jax.random.split(key, n - 1))
        return jnp.concatenate([start[:, None], seq.T], axis=1)

    def _ask(self, key: Array, state: PathState, problem: PathPlanning) -> tuple[Array, PathState]:
        k_walk, k_pair, k_cut, k_cross = jax.random.split(key, 4)
        paths = self._walk(k_walk, state, problem)
        cost = problem.step_cost.astype(jnp.float32)
        p = state.params
        m = self.num_ants
        partners = paths[jax.random.randint(k_pair, (m,), 0, m)]
        keys = jax.random.split(k_cut, m)
        children = jax.vmap(common_node_crossover)(keys, paths, partners)
        cross = jax.random.uniform(k_cross, (m,)) < p.p_crossover
        paths = jnp.where(cross[:, None], children, paths)
        cut = jax.vmap(shortcut, in_axes=(0, None))(paths, cost)
        paths = jnp.where(p.use_shortcut, cut, paths)
        return paths, state.replace(chaos_x=chaos.logistic_step(state.chaos_x))

    # ------------------------------------------------------------------ pheromone
    def _tell(
        self, state: PathState, paths: Array, lengths: Array, problem: PathPlanning
    ) -> tuple[PathState, dict[str, Array]]:
        p = state.params
        n = state.tau.shape[0]
        previous_best = state.best_cost
        state = record_best(state, paths, lengths)
        ok = jnp.isfinite(lengths)
        safe = jnp.where(ok, lengths, 1.0)
        mask = pheromone.elitist_deposit_mask(jnp.where(ok, lengths, jnp.inf), previous_best) & ok
        adaptive = pheromone.adaptive_weight(safe, jnp.where(jnp.isfinite(state.best_cost),
                                                             state.best_cost, 1.0))
        weights = mask * jnp.where(p.use_adaptive_weight, 2.0 * adaptive, 1.0)
        rho = pheromone.evaporation_schedule(p.rho, state.stagnation, p.stagnation_window,
                                             p.evaporation_slowdown)
        has_best = jnp.isfinite(state.best_cost)
        best_len = jnp.where(has_best, state.best_cost, 1.0)
        tau = pheromone.elitist_update(state.tau, paths, safe, weights, state.best_solution,
                                       best_len, rho, p.q, jnp.where(has_best, p.sigma, 0.0))
        tau_max, tau_min = pheromone.mmas_bounds(best_len, n, p.p_best, p.q * (1.0 + p.sigma))
        tau = jnp.where(has_best, pheromone.clamp(tau, tau_min, tau_max), tau)
        return state.replace(tau=tau), {"diversity": path_diversity(paths, n)}
