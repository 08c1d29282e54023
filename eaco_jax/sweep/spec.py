"""The sweep file: its keys, their checks, and the settings it lists.

A sweep spec (a dict, usually from YAML; the format reference is ``docs/sweeps.md``)::

    name: table3_g01          # optional, used in titles and the summary
    command: constrained      # a run kind (tsp, constrained, path, gait), or
    # kind: "package.module:KIND"  a RunKind object of your own
    args: {problem: g01, max_evaluations: 4000}   # fixed settings of that run kind
    seeds: 10                 # 0..9, or a list [3, 7, 11]
    cells: [{q0: 0.2, rho: 0.1}, ...]   # listed settings ...
    grid: {locality: [0.1, 0.2]}        # ... and/or a grid (crossed with the cells)
    # random: {n: 20, seed: 0, space: {q0: [0.1, 0.9], rho: {low: 0.01, high: 1, log: true},
    #                                  ants: {choice: [20, 40]}}}
    checkpoint_every: 50      # optional: checkpoint every group (resume inside a group)

Keys of ``args``, cells, grid and random spaces are the run kind's settings (the command's
flags, ``ants`` for ``--ants``) or fields of its strategy's Params (``q0``, ``rho``, ...).
"""

from __future__ import annotations

import importlib
import itertools
import math
import random
from typing import Any

from eaco_jax.errors import ConfigError

SPEC_KEYS = {"command", "kind", "args", "seeds", "grid", "cells", "random", "checkpoint_every",
             "name"}


def validate_spec(spec: Any) -> dict[str, Any]:
    """Check the spec's top-level shape; one clear ConfigError for anything malformed."""
    if not isinstance(spec, dict):
        raise ConfigError("a sweep spec must be a mapping (YAML dict) at the top level")
    unknown = set(spec) - SPEC_KEYS
    if unknown:
        raise ConfigError(f"unknown sweep keys {sorted(unknown)}; allowed: {sorted(SPEC_KEYS)}")
    if ("command" in spec) == ("kind" in spec):
        raise ConfigError("a sweep spec needs exactly one of 'command' (tsp, constrained, path, "
                          "gait) or 'kind' ('module:attribute' of a RunKind)")
    if "random" in spec and ("grid" in spec or "cells" in spec):
        raise ConfigError("use either 'random' or 'grid'/'cells' in one sweep, not both")
    for key in ("args", "grid", "random"):
        if key in spec and not isinstance(spec[key], dict):
            raise ConfigError(f"sweep '{key}' must be a mapping")
    if "cells" in spec and not (isinstance(spec["cells"], list)
                                and all(isinstance(c, dict) for c in spec["cells"])):
        raise ConfigError("sweep 'cells' must be a list of mappings")
    for name, values in (spec.get("grid") or {}).items():
        if not isinstance(values, list) or not values:
            raise ConfigError(f"grid entry {name!r} must be a non-empty list")
    every = spec.get("checkpoint_every")
    if every is not None and (not isinstance(every, int) or isinstance(every, bool) or every < 1):
        raise ConfigError(f"checkpoint_every must be an integer >= 1, got {every!r}")
    seeds_of(spec)
    return spec


def run_kind(spec: dict[str, Any]) -> Any:
    """The spec's run kind: a registered one by ``command``, or ``kind: "module:attr"``."""
    from eaco_jax.runs import RunKind, get

    if "command" in spec:
        return get(str(spec["command"]))
    name = str(spec["kind"])
    module, _, attr = name.partition(":")
    if not attr:
        raise ConfigError(f"kind must look like 'package.module:KIND', got {name!r}")
    try:
        kind = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as err:
        raise ConfigError(f"cannot import sweep kind {name!r}: {err}") from None
    if not isinstance(kind, RunKind):
        raise ConfigError(f"sweep kind {name!r} is a {type(kind).__name__}, not a RunKind")
    return kind


def seeds_of(spec: dict[str, Any]) -> list[int]:
    """``seeds: 10`` means 0..9; a list is taken as it is."""
    seeds = spec.get("seeds", 1)
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            raise ConfigError(f"seeds must be >= 1, got {seeds}")
        if seeds > 2**20:
            raise ConfigError(f"seeds: {seeds} seeds is more than 2**20; list the seeds you want")
        return list(range(seeds))
    if isinstance(seeds, list) and seeds and all(
            isinstance(s, int) and not isinstance(s, bool) for s in seeds):
        bad = [s for s in seeds if not 0 <= s <= 2**32 - 1]
        if bad:
            raise ConfigError(f"seeds: {bad[0]} is outside the range 0..4294967295")
        return [int(s) for s in seeds]
    raise ConfigError(f"seeds must be a positive int or a list of ints, got {seeds!r}")


def settings_list(spec: dict[str, Any]) -> list[dict[str, Any]]:
    """The swept values of every cell, in order (listed cells x grid, or random draws)."""
    if "random" in spec:
        return random_settings(spec["random"])
    base = spec.get("cells") or [{}]
    grid = spec.get("grid") or {}
    names = list(grid)
    product = [dict(zip(names, combo, strict=True))
               for combo in itertools.product(*(grid[n] for n in names))]
    return [{**cell, **combo} for cell in base for combo in product]


def random_settings(rnd: dict[str, Any]) -> list[dict[str, Any]]:
    """``n`` settings drawn from ``space`` with ``random.Random(seed)``."""
    n, space = rnd.get("n"), rnd.get("space")
    if not isinstance(n, int) or n < 1 or not isinstance(space, dict) or not space:
        raise ConfigError("random sweeps need 'n' (>= 1) and a 'space' mapping")
    rng = random.Random(int(rnd.get("seed", 0)))
    out = []
    for _ in range(n):
        cell = {}
        for name, dist in space.items():
            if isinstance(dist, list) and len(dist) == 2:
                dist = {"low": dist[0], "high": dist[1]}
            if isinstance(dist, dict) and "choice" in dist:
                cell[name] = rng.choice(list(dist["choice"]))
            elif isinstance(dist, dict) and "low" in dist and "high" in dist:
                lo, hi = float(dist["low"]), float(dist["high"])
                if not lo < hi:
                    raise ConfigError(f"random space {name!r}: low must be < high")
                if dist.get("log"):
                    if lo <= 0:
                        raise ConfigError(f"random space {name!r}: log range needs low > 0")
                    cell[name] = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
                else:
                    cell[name] = rng.uniform(lo, hi)
            else:
                raise ConfigError(
                    f"random space {name!r} must be [low, high], {{low, high, log}} or "
                    "{choice: [...]}")
        out.append(cell)
    return out
