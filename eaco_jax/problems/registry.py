"""Problems by name, as brax's ``get_environment``: ``problems.get("eil51")``.

A *family* is registered with a factory (``register("tsp", load_tsplib)``); ``get(name, **kw)``
calls the family's factory, and for convenience also resolves a bare instance name that
belongs to a family: a bundled TSPLIB instance or a ``.tsp`` path (``tsp``), a CEC2006 problem
``g01``..``g13`` / ``G1``..``G4`` (``cec2006``), a test function (``sphere``, ...). Factories are
imported on first use, so asking for a TSP never imports MuJoCo.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from eaco_jax.errors import ProblemError

#: family -> factory, or "module:function" imported on first use
_FAMILIES: dict[str, Callable[..., Any] | str] = {
    "tsp": "eaco_jax.problems.tsp:load_tsplib",
    "cec2006": "eaco_jax.problems.cec2006:cec2006",
    "path": "eaco_jax.problems.path_planning:random_environment",
    "path-paper": "eaco_jax.problems.path_planning:paper_environment",
    "gait": "eaco_jax.problems.gait:make_gait_problem",
    "sphere": "eaco_jax.problems.functions:sphere",
    "rosenbrock": "eaco_jax.problems.functions:rosenbrock",
    "rastrigin": "eaco_jax.problems.functions:rastrigin",
    "ackley": "eaco_jax.problems.functions:ackley",
    "zdt1": "eaco_jax.problems.multiobjective:zdt1",
    "zdt2": "eaco_jax.problems.multiobjective:zdt2",
    "zdt3": "eaco_jax.problems.multiobjective:zdt3",
    "dtlz2": "eaco_jax.problems.multiobjective:dtlz2",
    "rastrigin-proj": "eaco_jax.problems.qd:rastrigin_proj",
}


def register(name: str, factory: Callable[..., Any] | str) -> None:
    """Make ``get(name, **kw)`` call ``factory(**kw)`` (a callable or ``"module:function"``)."""
    _FAMILIES[str(name)] = factory


def families() -> list[str]:
    """Registered family names."""
    return sorted(_FAMILIES)


def _factory(name: str) -> Callable[..., Any]:
    entry = _FAMILIES[name]
    if isinstance(entry, str):
        module, _, attr = entry.partition(":")
        entry = getattr(importlib.import_module(module), attr)
    return entry


def get(name: str, /, **kwargs: Any) -> Any:
    """The problem ``name`` built with ``kwargs``.

    ``name`` is a family (``"tsp"``, ``"cec2006"``, ``"path"``, ``"gait"``, ``"sphere"``, ...,
    whose factory gets ``kwargs``) or an instance of one: ``"eil51"`` or ``"path/to/x.tsp"``
    (TSPLIB), ``"g10"`` or ``"G2"`` (CEC2006).
    """
    from eaco_jax.problems.cec2006 import BUILDERS, PAPER_NAMES
    from eaco_jax.problems.tsp import bundled_path

    text = str(name)
    if text in _FAMILIES:
        return _factory(text)(**kwargs)
    if bundled_path(text) is not None or text.endswith(".tsp") or Path(text).suffix == ".tsp":
        return _factory("tsp")(text, **kwargs)
    if text.lower() in BUILDERS or text.upper() in PAPER_NAMES:
        if kwargs:
            raise ProblemError(f"CEC2006 problem {text!r} takes no options, got {sorted(kwargs)}")
        return _factory("cec2006")(text)
    raise ProblemError(
        f"unknown problem {text!r}; use a family ({', '.join(families())}), a bundled TSPLIB "
        "instance (eaco_jax.problems.tsp.bundled_instances()), a .tsp path or g01..g13"
    )
