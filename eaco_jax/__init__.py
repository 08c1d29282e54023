"""eaco_jax: enhanced elitist-mutated ant colony optimisation (EACO) in JAX.

Quick start::

    import eaco_jax as ea
    result = ea.minimize(ea.problems.load_tsplib("eil51"), seed=0, iterations=200)
"""

from eaco_jax import problems
from eaco_jax.driver.minimize import Result, minimize
from eaco_jax.problems.base import Evaluation, ProblemError
from eaco_jax.strategies.base import State, Strategy

__version__ = "0.1.0"

__all__ = [
    "Evaluation",
    "ProblemError",
    "Result",
    "State",
    "Strategy",
    "__version__",
    "minimize",
    "problems",
]
