"""eaco_jax: enhanced elitist-mutated ant colony optimisation (EACO) in JAX.

Quick start::

    import eaco_jax as ea
    result = ea.minimize(ea.problems.get("eil51"), seed=0, iterations=200)

Layers, each importing only those below it: ``problems`` <- ``strategies`` <- ``driver``
(``minimize``, stop rules, ``Checkpointing``) <- ``runs`` <- ``cli`` and ``sweep``.
"""

import os as _os
import sys as _sys

if _os.path.basename(_sys.argv[0] if _sys.argv else "") in ("eaco", "-m"):
    # the `eaco` command: jaxlib logs two false "machine feature not supported" errors per
    # program it loads from the persistent compilation cache; keep stderr to what we say
    _os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    # Ctrl-C while the command still imports (jax, typer: about a second) is one line, not a
    # traceback through the import machinery; `eaco_jax.cli.main` hands SIGINT back to Python
    import signal as _signal

    def _interrupted_while_starting(signum: int, frame: object) -> None:
        _sys.stderr.write("interrupted\n")
        _sys.stderr.flush()
        _os._exit(130)

    _signal.signal(_signal.SIGINT, _interrupted_while_starting)

from eaco_jax import problems, strategies  # noqa: E402
from eaco_jax._version import __version__  # noqa: E402
from eaco_jax.driver import stop  # noqa: E402
from eaco_jax.driver.minimize import Checkpointing, Result, minimize  # noqa: E402
from eaco_jax.errors import CheckpointError, ConfigError, Interrupted, ProblemError, UserError  # noqa: E402
from eaco_jax.problems.base import Evaluation  # noqa: E402
from eaco_jax.strategies.base import State, Strategy  # noqa: E402

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
