"""Colony strategies: one module per algorithm, each a pure init/ask/tell over a pytree state."""

from eaco_jax.strategies.base import State, Strategy
from eaco_jax.strategies.continuous_eaco import ContinuousEACO, ContinuousParams, ContinuousState
from eaco_jax.strategies.graph_eaco import GraphEACO, GraphParams, GraphState
from eaco_jax.strategies.islands import Islands, IslandsState
from eaco_jax.strategies.path_eaco import PathEACO, PathParams, PathState

__all__ = [
    "State", "Strategy", "ContinuousEACO", "ContinuousParams", "ContinuousState", "GraphEACO",
    "GraphParams", "GraphState", "Islands", "IslandsState", "PathEACO", "PathParams", "PathState",
]
