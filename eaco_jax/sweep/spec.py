"""The sweep file: its keys, their checks, and the settings it lists.

A sweep spec (a dict, usually from YAML; the format reference is ``docs/sweeps.md``)::

    name: table3_g01          # optional, used in titles and the summary
    command: constrained      # a run kind (tsp, constrained, path, gait), or
    # kind: "package.module:KIND"  a RunKind object of your own
    args: {problem: g01, max_evaluations: 4000}   # fixed settings of that run kind
    seeds: 10                 # 0..9, or a list [3, 7, 11] (at most 65,536 seeds)
    cells: [{q0: 0.2, rho: 0.1}, ...]   # listed settings ...
    grid: {locality: [0.1, 0.2]}        # ... and/or a grid (crossed with the cells)
    # random: {n: 20, seed: 0, space: {q0: [0.1, 0.9], rho: {low: 0.01, high: 1, log: true},
    #                                  ants: {choice: [20, 40]}}}
    checkpoint_every: 50      # optional: checkpoint every group (resume inside a group)
    max_cells: 100000         # optional: the most cells the sweep may have

Keys of ``args``, cells, grid and random spaces are the run kind's settings (the command's
flags, ``ants`` for ``--ants``) or fields of its strategy's Params (``q0``, ``rho``, ...).

The raw mapping is checked and typed ONCE, by :func:`parse_spec` (or :func:`load_spec` for a
file), into a :class:`SweepSpec`; the rest of the sweep code reads only that. Everything a
file can make large is bounded before it is built: YAML aliases (expanded size counted on the
node graph), swept values (one scalar each), the number of cells (counted as a product before
any product is built) and the seeds.
"""

from __future__ import annotations

import dataclasses
import importlib
import itertools
import math
import random
from pathlib import Path
from typing import Any

from eaco_jax.errors import ConfigError

SPEC_KEYS = {"command", "kind", "args", "seeds", "grid", "cells", "random", "checkpoint_every",
             "name", "max_cells"}
RANDOM_KEYS = {"n", "seed", "space"}
#: default most cells of one sweep (``max_cells:`` in the file or ``--max-cells`` raise it)
MAX_CELLS = 100_000
#: most seeds of one sweep: each cell's seeds are rows of one vmapped call
MAX_SEEDS = 2**16
#: host memory one vmapped row costs besides its colony state (keys, arrays, table rows): an
#: upper bound of the peak resident memory per row of large many-seed sweeps on a CPU
HOST_ROW_BYTES = 32 * 1024
#: most nodes a sweep file may expand to (every use of an alias counted)
MAX_YAML_NODES = 2_000_000

Scalar = bool | int | float | str | None


@dataclasses.dataclass(frozen=True)
class RandomSpace:
    """``random:`` of a sweep: ``n`` draws of ``space`` with ``random.Random(seed)``.

    ``space`` maps a key to ``("uniform", low, high, log)`` or ``("choice", values)``.
    """

    n: int
    seed: int
    space: dict[str, tuple[Any, ...]]


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A checked sweep file: what every other part of the sweep code reads."""

    name: str | None
    command: str | None  # a registered run kind ...
    kind_ref: str | None  # ... or "module:attribute" of a RunKind
    run_kind: Any = dataclasses.field(repr=False, compare=False)
    args: dict[str, Scalar] = dataclasses.field(default_factory=dict)
    seeds: tuple[int, ...] = (0,)
    cells: tuple[dict[str, Scalar], ...] = ()
    grid: dict[str, tuple[Scalar, ...]] = dataclasses.field(default_factory=dict)
    random: RandomSpace | None = None
    checkpoint_every: int | None = None
    max_cells: int = MAX_CELLS

    @property
    def num_cells(self) -> int:
        """Cells the sweep has, counted without building any of them."""
        return count_cells(len(self.cells), [len(v) for v in self.grid.values()], self.random)

    def to_dict(self) -> dict[str, Any]:
        """The spec as plain JSON values (what ``OUT/spec.json`` holds)."""
        out: dict[str, Any] = {"name": self.name, "command": self.command, "kind": self.kind_ref,
                               "args": self.args}
        n = len(self.seeds)
        out["seeds"] = n if self.seeds == tuple(range(n)) else list(self.seeds)
        if self.random is not None:
            out["random"] = {"n": self.random.n, "seed": self.random.seed,
                             "space": {k: list(v) for k, v in self.random.space.items()}}
        else:
            out["cells"] = list(self.cells)
            out["grid"] = {k: list(v) for k, v in self.grid.items()}
        out["checkpoint_every"] = self.checkpoint_every
        out["max_cells"] = self.max_cells
        return {k: v for k, v in out.items() if v is not None}


def parse_spec(raw: Any, *, max_cells: int | None = None) -> SweepSpec:
    """Check a sweep mapping and type it (a :class:`SweepSpec` is returned as it is).

    ``max_cells`` overrides the file's ``max_cells`` (the command's ``--max-cells``)."""
    if isinstance(raw, SweepSpec):
        if max_cells is None or max_cells == raw.max_cells:
            return raw
        limit = _positive("max_cells", max_cells)
        _check_count(raw.num_cells, limit, _formula(raw.cells, raw.grid, raw.random))
        return dataclasses.replace(raw, max_cells=limit)
    return _from_raw(raw, max_cells)


def load_spec(path: str | Path, *, max_cells: int | None = None) -> SweepSpec:
    """Read and check a sweep YAML file (one-line errors for missing or malformed files)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"sweep file {path} does not exist")
    raw = load_yaml(path.read_text(), where=f"sweep file {path}")
    if not isinstance(raw, dict):
        raise ConfigError(f"sweep file {path} must hold a mapping (name, command, args, ...)")
    return parse_spec(raw, max_cells=max_cells)


# --------------------------------------------------------------------------- YAML
def load_yaml(text: str, where: str = "sweep file") -> Any:
    """``yaml.safe_load`` that refuses a document expanding to more than
    :data:`MAX_YAML_NODES` nodes (every use of an alias counted, on the node graph, so an
    alias bomb is refused without being expanded) or holding a recursive alias."""
    import yaml

    class BoundedLoader(yaml.SafeLoader):
        def compose_document(self) -> Any:
            node = super().compose_document()
            _check_expanded_size(node, where)
            return node

    try:
        return yaml.load(text, Loader=BoundedLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as err:
        first = str(err).splitlines()[0]
        raise ConfigError(f"{where} is not valid YAML: {first}") from None
    except RecursionError:
        raise ConfigError(f"{where} is nested too deeply to be a sweep file") from None


def _check_expanded_size(root: Any, where: str) -> None:
    """Count the nodes the YAML node graph ``root`` expands to, each shared node once
    (memoised, without recursion); refuse above :data:`MAX_YAML_NODES` or on a cycle."""
    import yaml

    def children(node: Any) -> list[Any]:
        if isinstance(node, yaml.MappingNode):
            return [n for pair in node.value for n in pair]
        if isinstance(node, yaml.SequenceNode):
            return list(node.value)
        return []

    sizes: dict[int, int] = {}
    open_: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, finished = stack.pop()
        key = id(node)
        if finished:
            open_.discard(key)
            sizes[key] = 1 + sum(sizes[id(c)] for c in children(node))
            if sizes[key] > MAX_YAML_NODES:
                raise ConfigError(
                    f"{where} expands to more than {MAX_YAML_NODES:,} values (through its "
                    "aliases); write the sweep out without nested aliases")
            continue
        if key in sizes:
            continue
        if key in open_:
            raise ConfigError(f"{where} holds a recursive alias (a value that contains "
                              "itself); write the sweep out without it")
        open_.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children(node) if id(c) not in sizes)


# --------------------------------------------------------------------------- parsing
def _from_raw(raw: Any, max_cells: int | None) -> SweepSpec:
    """The checks, in the order that refuses the cheapest and largest mistakes first."""
    if not isinstance(raw, dict):
        raise ConfigError("a sweep spec must be a mapping (YAML dict) at the top level")
    unknown = set(raw) - SPEC_KEYS
    if unknown:
        raise ConfigError(f"unknown sweep keys {sorted(map(str, unknown))}; allowed: "
                          f"{sorted(SPEC_KEYS)}")
    if ("command" in raw) == ("kind" in raw):
        raise ConfigError("a sweep spec needs exactly one of 'command' (tsp, constrained, path, "
                          "gait) or 'kind' ('module:attribute' of a RunKind)")
    if "random" in raw and ("grid" in raw or "cells" in raw):
        raise ConfigError("use either 'random' or 'grid'/'cells' in one sweep, not both")
    for key in ("args", "grid", "random"):
        if key in raw and not isinstance(raw[key], dict):
            raise ConfigError(f"sweep '{key}' must be a mapping")
    for key in ("name", "command", "kind"):
        if key in raw and not isinstance(raw[key], str | None):
            raise ConfigError(f"sweep '{key}' must be a string, got {_short(raw[key])}")
    if "cells" in raw and not (isinstance(raw["cells"], list)
                               and all(isinstance(c, dict) for c in raw["cells"])):
        raise ConfigError("sweep 'cells' must be a list of mappings")
    args = _scalars(raw.get("args") or {}, "sweep args")
    cells = tuple(_scalars(c, f"sweep cell {i}", hint="give each value its own cell, or sweep "
                           "them with grid: {{{key}: [...]}}")
                  for i, c in enumerate(raw.get("cells") or []))
    grid: dict[str, tuple[Scalar, ...]] = {}
    for name, values in (raw.get("grid") or {}).items():
        if not isinstance(values, list) or not values:
            raise ConfigError(f"grid entry {name!r} must be a non-empty list")
        grid[_name(name, "grid")] = tuple(
            _scalar(v, f"grid entry {name!r} value {j}", "a grid entry is a flat list of "
                    "numbers, strings or booleans") for j, v in enumerate(values))
    rnd = _random(raw["random"]) if "random" in raw else None
    limit = _positive("max_cells", raw.get("max_cells", MAX_CELLS) if max_cells is None
                      else max_cells)
    _check_count(count_cells(len(cells), [len(v) for v in grid.values()], rnd), limit,
                 _formula(cells, grid, rnd))
    every = raw.get("checkpoint_every")
    if every is not None:
        every = _positive("checkpoint_every", every)
    seeds = _seeds(raw.get("seeds", 1))
    command = raw.get("command")
    kind_ref = raw.get("kind")
    return SweepSpec(name=raw.get("name"), command=command, kind_ref=kind_ref,
                     run_kind=resolve_kind(command, kind_ref), args=args, seeds=seeds,
                     cells=cells, grid=grid, random=rnd, checkpoint_every=every,
                     max_cells=limit)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _name(key: Any, where: str) -> str:
    if not isinstance(key, str):
        raise ConfigError(f"{where}: key {_short(key)} is not a name (a setting or Params field)")
    return key


def _scalar(value: Any, where: str, hint: str) -> Scalar:
    """``value`` if it is one number, string, boolean or null; else one line naming it."""
    if value is None or isinstance(value, bool | int | float | str):
        return value
    what = {list: "a list", dict: "a mapping"}.get(type(value), f"a {type(value).__name__}")
    raise ConfigError(f"{where}: {_short(value)} is {what}, not one value; {hint}")


def _scalars(mapping: dict[Any, Any], where: str, hint: str = "a setting takes one number, "
             "string or boolean") -> dict[str, Scalar]:
    return {_name(k, where): _scalar(v, f"{where} key {k!r}", hint.format(key=k))
            for k, v in mapping.items()}


def _positive(what: str, value: Any) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < 1:
        raise ConfigError(f"{what} must be an integer >= 1, got {_short(value)}")
    return value


def _random(rnd: dict[Any, Any]) -> RandomSpace:
    unknown = set(rnd) - RANDOM_KEYS
    if unknown:
        raise ConfigError(f"unknown random keys {sorted(map(str, unknown))}; allowed: n, seed, "
                          "space")
    n, space, seed = rnd.get("n"), rnd.get("space"), rnd.get("seed", 0)
    if (not isinstance(n, int) or isinstance(n, bool) or n < 1 or not isinstance(space, dict)
            or not space):
        raise ConfigError("random sweeps need 'n' (>= 1) and a 'space' mapping")
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise ConfigError(f"random seed must be an integer, got {_short(seed)}")
    out: dict[str, tuple[Any, ...]] = {}
    for name, dist in space.items():
        where = f"random space {_name(name, 'random space')!r}"
        if isinstance(dist, list) and len(dist) == 2:
            dist = {"low": dist[0], "high": dist[1]}
        if isinstance(dist, dict) and set(dist) == {"choice"} and isinstance(
                dist["choice"], list) and dist["choice"]:
            out[name] = ("choice", tuple(_scalar(v, f"{where} choice {j}", "choices are "
                                                 "numbers, strings or booleans")
                                         for j, v in enumerate(dist["choice"])))
        elif isinstance(dist, dict) and {"low", "high"} <= set(dist) <= {"low", "high", "log"}:
            lo, hi, log = _number(dist["low"], where), _number(dist["high"], where), dist.get(
                "log", False)
            if not isinstance(log, bool):
                raise ConfigError(f"{where}: log must be true or false")
            if not lo < hi:
                raise ConfigError(f"{where}: low must be < high")
            if log and lo <= 0:
                raise ConfigError(f"{where}: log range needs low > 0")
            out[name] = ("uniform", lo, hi, log)
        else:
            raise ConfigError(f"{where} must be [low, high], {{low, high, log}} or "
                              "{choice: [...]}")
    return RandomSpace(n, seed, out)


def _number(value: Any, where: str) -> float:
    """A bound of a random range as a float (YAML reads ``1e-3`` as a string)."""
    try:
        if isinstance(value, bool):
            raise TypeError
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: low and high must be numbers, got {_short(value)}") from None
    if not math.isfinite(number):
        raise ConfigError(f"{where}: low and high must be finite, got {_short(value)}")
    return number


def count_cells(listed: int, grid_lengths: list[int], rnd: RandomSpace | None) -> int:
    """Cells of a sweep: ``random.n``, or listed cells (one if none) x the grid's product."""
    if rnd is not None:
        return rnd.n
    return max(listed, 1) * math.prod(grid_lengths)


def _formula(cells: tuple[Any, ...], grid: dict[str, tuple[Any, ...]],
             rnd: RandomSpace | None) -> str:
    if rnd is not None:
        return "random n"
    parts = ([f"{len(cells)} listed"] if cells else []) + [
        f"{len(v)} {k}" for k, v in grid.items()]
    return " x ".join(parts) or "one cell"


def _check_count(n: int, limit: int, formula: str) -> None:
    if n > limit:
        raise ConfigError(
            f"the sweep has {n:,} cells ({formula}), more than max_cells={limit:,}; sweep "
            "fewer values, or raise the limit (max_cells: N in the file, or --max-cells N)")


def _seeds(seeds: Any) -> tuple[int, ...]:
    """``seeds: 10`` means 0..9; a list is taken as it is; at most :data:`MAX_SEEDS`."""
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            raise ConfigError(f"seeds must be >= 1, got {seeds}")
        _check_seed_count(seeds)
        return tuple(range(seeds))
    if isinstance(seeds, list) and seeds and all(
            isinstance(s, int) and not isinstance(s, bool) for s in seeds):
        _check_seed_count(len(seeds))
        bad = [s for s in seeds if not 0 <= s <= 2**32 - 1]
        if bad:
            raise ConfigError(f"seeds: {bad[0]} is outside the range 0..4294967295")
        return tuple(int(s) for s in seeds)
    raise ConfigError(f"seeds must be a positive int or a list of ints, got {_short(seeds)}")


def _check_seed_count(n: int) -> None:
    if n > MAX_SEEDS:
        need = n * HOST_ROW_BYTES / 2**30
        raise ConfigError(
            f"seeds: {n:,} seeds is more than the {MAX_SEEDS:,} a sweep runs (each cell's seeds "
            f"are rows of one vmapped call: {n:,} rows need about {need:.0f} GiB of host "
            "memory); run fewer seeds, or split them over sweeps with seed lists")


def resolve_kind(command: str | None, kind_ref: str | None) -> Any:
    """The run kind: a registered one by ``command``, or ``kind_ref`` ("module:attr")."""
    from eaco_jax.runs import RunKind, get

    if command is not None:
        return get(str(command))
    name = str(kind_ref)
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


# --------------------------------------------------------------------------- cells
def settings_list(spec: SweepSpec) -> list[dict[str, Any]]:
    """The swept values of every cell, in order (listed cells x grid, or random draws); the
    count is bounded by ``spec.max_cells`` when the spec is parsed."""
    if spec.random is not None:
        return random_settings(spec.random)
    base = list(spec.cells) or [{}]
    names = list(spec.grid)
    return [{**cell, **dict(zip(names, combo, strict=True))}
            for cell in base for combo in itertools.product(*(spec.grid[n] for n in names))]


def random_settings(rnd: RandomSpace) -> list[dict[str, Any]]:
    """``n`` settings drawn from ``space`` with ``random.Random(seed)``."""
    rng = random.Random(rnd.seed)
    out = []
    for _ in range(rnd.n):
        cell = {}
        for name, dist in rnd.space.items():
            if dist[0] == "choice":
                cell[name] = rng.choice(list(dist[1]))
            else:
                _, lo, hi, log = dist
                if log:
                    cell[name] = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
                else:
                    cell[name] = rng.uniform(lo, hi)
        out.append(cell)
    return out
