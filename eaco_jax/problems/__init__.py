"""Problem families (they know nothing about strategies)."""

from eaco_jax.problems.tsp import TSP, load_tsplib

__all__ = ["TSP", "load_tsplib"]
