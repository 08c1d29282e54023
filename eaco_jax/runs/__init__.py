"""Run kinds: one module per kind of run (tsp, constrained, path, gait, gait-eval), each owning
its settings, how it builds problem + strategy, how it runs with checkpointing and what it
writes. The command line and the sweeps call them; ``get(name)`` finds one, ``resume(DIR)``
continues a checkpointed run."""

from eaco_jax.runs.base import Built, RunKind, settings_dict
from eaco_jax.runs.registry import checkpoint_kind, get, kinds, register, resume

__all__ = ["Built", "RunKind", "checkpoint_kind", "get", "kinds", "register", "resume",
           "settings_dict"]
