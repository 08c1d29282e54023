"""Colony strategies: one module per algorithm."""
from eaco_jax.strategies.graph_eaco import GraphEACO, GraphParams, GraphState  # noqa: F401
