"""The errors a user can cause, each answered by one line that names the fix.

Anything else raised inside eaco_jax is a bug and keeps its traceback: the command line turns
only :class:`UserError` (and its subclasses) into a one-line message and exit code 2.
"""

from __future__ import annotations


class UserError(ValueError):
    """Bad input from the user; the message says what is wrong and how to fix it."""


class ProblemError(UserError):
    """A problem definition or input file is invalid."""


class ConfigError(UserError):
    """A setting, hyper-parameter, sweep cell or command-line value is out of range or unknown."""


class CheckpointError(UserError):
    """A checkpoint cannot be used for this run (another run, corrupt, other format)."""


class Interrupted(KeyboardInterrupt):
    """SIGINT / SIGTERM stopped a run; ``result`` holds what it had found (or None).

    A ``KeyboardInterrupt``, so code that stops on Ctrl-C still does; the command line
    prints its message as one line (exit code 130).
    """

    def __init__(self, message: str, result: object = None) -> None:
        super().__init__(message)
        self.result = result

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "interrupted"
