"""Problem families (they know nothing about strategies); ``get(name, **kw)`` finds one by name."""

from eaco_jax.problems.base import Evaluation, Problem
from eaco_jax.problems.cec2006 import cec2006
from eaco_jax.problems.constrained import ConstrainedProblem, float64
from eaco_jax.problems.functions import ackley, rastrigin, rosenbrock, sphere
from eaco_jax.problems.multiobjective import MultiObjectiveProblem, dtlz2, zdt1, zdt2, zdt3
from eaco_jax.problems.path_planning import PathPlanning, paper_environment, random_environment
from eaco_jax.problems.registry import families, get, register
from eaco_jax.problems.tsp import TSP, load_tsplib

__all__ = [
    "TSP", "load_tsplib", "ConstrainedProblem", "cec2006", "float64", "sphere", "rosenbrock",
    "rastrigin", "ackley", "PathPlanning", "paper_environment", "random_environment",
    "Evaluation", "Problem", "get", "register", "families", "MultiObjectiveProblem", "zdt1",
    "zdt2", "zdt3", "dtlz2",
]
