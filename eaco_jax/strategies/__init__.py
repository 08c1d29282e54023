"""Colony strategies: one module per algorithm."""
from eaco_jax.strategies.continuous_eaco import (  # noqa: F401
    ContinuousEACO,
    ContinuousParams,
    ContinuousState,
)
from eaco_jax.strategies.graph_eaco import GraphEACO, GraphParams, GraphState  # noqa: F401
