"""Colony strategies: one module per algorithm, each a pure init/ask/tell over a pytree state.

EACO: :class:`GraphEACO` (TSP; ``preset="paper" | "mmas" | "default"``), :class:`ContinuousEACO`,
:class:`PathEACO`, :class:`MOEACO` (several objectives: Pareto-ranked archive),
:class:`MAPElites` (quality diversity: a grid archive of elites; ``variation="eaco"`` samples
around them with the colony's kernel, ``"isoline"`` is the baseline). Baselines in
the same contract (vmapped populations, same driver, checkpoints and sweeps): ant system / EAS,
ACS, MMAS (a GraphEACO preset), annealing and tabu search on tours; PSO, real-coded GA,
simulated annealing and tabu search on continuous problems; random search.
``get(name, **fields)`` builds one by name (``names()`` lists them).
"""

from __future__ import annotations

import importlib
from typing import Any

from eaco_jax.errors import ConfigError
from eaco_jax.strategies.acs import AntColonySystem
from eaco_jax.strategies.ant_system import AntSystem
from eaco_jax.strategies.base import State, Strategy
from eaco_jax.strategies.continuous_eaco import ContinuousEACO, ContinuousParams, ContinuousState
from eaco_jax.strategies.graph_eaco import GraphEACO, GraphParams, GraphState
from eaco_jax.strategies.islands import Islands, IslandsState
from eaco_jax.strategies.map_elites import MAPElites, MAPElitesParams, MAPElitesState
from eaco_jax.strategies.mo_eaco import MOEACO, MOParams, MOState
from eaco_jax.strategies.path_eaco import PathEACO, PathParams, PathState
from eaco_jax.strategies.pso import PSO
from eaco_jax.strategies.random_search import RandomSearch, RandomTours
from eaco_jax.strategies.real_ga import RealGA
from eaco_jax.strategies.simulated_annealing import SimulatedAnnealing
from eaco_jax.strategies.tabu_search import TabuSearch
from eaco_jax.strategies.tour_annealing import TourAnnealing
from eaco_jax.strategies.tour_tabu import TourTabu

#: name -> (class path, fixed fields)
_REGISTRY: dict[str, tuple[str, dict[str, Any]]] = {
    "eaco": ("graph_eaco:GraphEACO", {}),
    "eaco-paper": ("graph_eaco:GraphEACO", {"preset": "paper"}),
    "mmas": ("graph_eaco:GraphEACO", {"preset": "mmas", "crossover": "none",
                                      "mutation": "none"}),
    "as": ("ant_system:AntSystem", {}),
    "eas": ("ant_system:AntSystem", {"elitist": True}),
    "acs": ("acs:AntColonySystem", {}),
    "tour-sa": ("tour_annealing:TourAnnealing", {}),
    "tour-tabu": ("tour_tabu:TourTabu", {}),
    "random-tours": ("random_search:RandomTours", {}),
    "continuous-eaco": ("continuous_eaco:ContinuousEACO", {}),
    "continuous-eaco-df": ("continuous_eaco:ContinuousEACO", {"refine_ants": 0,
                                                              "repair_steps": 0}),
    "pso": ("pso:PSO", {}),
    "ga": ("real_ga:RealGA", {}),
    "sa": ("simulated_annealing:SimulatedAnnealing", {}),
    "tabu": ("tabu_search:TabuSearch", {}),
    "random": ("random_search:RandomSearch", {}),
    "path-eaco": ("path_eaco:PathEACO", {}),
    "path-ga": ("path_ga:PathGA", {}),
    "mo-eaco": ("mo_eaco:MOEACO", {}),
    "map-elites": ("map_elites:MAPElites", {"variation": "isoline"}),
    "map-elites-eaco": ("map_elites:MAPElites", {"variation": "eaco"}),
}


def names() -> list[str]:
    """The names :func:`get` knows."""
    return sorted(_REGISTRY)


def get(name: str, **fields: Any) -> Strategy:
    """A strategy by name, e.g. ``get("acs", num_ants=10, local_search="2opt")``."""
    if name not in _REGISTRY:
        raise ConfigError(f"unknown strategy {name!r}; choose one of {names()}")
    path, fixed = _REGISTRY[name]
    module, cls = path.split(":")
    klass = getattr(importlib.import_module(f"eaco_jax.strategies.{module}"), cls)
    return klass(**{**fixed, **fields})


__all__ = [
    "State", "Strategy", "ContinuousEACO", "ContinuousParams", "ContinuousState", "GraphEACO",
    "GraphParams", "GraphState", "Islands", "IslandsState", "PathEACO", "PathParams",
    "PathState", "AntSystem", "AntColonySystem", "TourAnnealing", "TourTabu", "RandomTours",
    "RandomSearch", "PSO", "RealGA", "SimulatedAnnealing", "TabuSearch", "get", "names",
    "MOEACO", "MOParams", "MOState", "MAPElites", "MAPElitesParams", "MAPElitesState",
]
