"""eaco_jax: enhanced elitist-mutated ant colony optimisation (EACO) in JAX.

Quick start::

    import eaco_jax as ea
    result = ea.minimize(ea.problems.get("eil51"), seed=0, iterations=200)

Layers, each importing only those below it: ``problems`` <- ``strategies`` <- ``driver``
(``minimize``, stop rules, ``Checkpointing``) <- ``runs`` <- ``cli`` and ``sweep``.
"""

from eaco_jax import problems, strategies
from eaco_jax._version import __version__
from eaco_jax.driver import stop
from eaco_jax.driver.minimize import Checkpointing, Result, minimize
from eaco_jax.errors import CheckpointError, ConfigError, Interrupted, ProblemError, UserError
from eaco_jax.problems.base import Evaluation
from eaco_jax.strategies.base import State, Strategy

__all__ = [
    "CheckpointError",
    "Checkpointing",
    "ConfigError",
    "Evaluation",
    "Interrupted",
    "ProblemError",
    "Result",
    "State",
    "Strategy",
    "UserError",
    "__version__",
    "minimize",
    "problems",
    "stop",
    "strategies",
]
