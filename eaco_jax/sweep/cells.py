"""Cells of a sweep: one setting of the swept keys each, split into static settings (a group
per distinct set: one compiled, vmapped call) and traced Params overrides."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import warnings
from typing import Any

import numpy as np

from eaco_jax.errors import ConfigError
from eaco_jax.runs.base import params_with
from eaco_jax.sweep.spec import SweepSpec, parse_spec, settings_list

#: settings a sweep sets itself (seeds from the spec, outputs in the sweep folder)
RESERVED = ("seed", "out")


@dataclasses.dataclass
class Cell:
    """One setting of the swept keys: static run settings and traced params overrides."""

    id: str
    values: dict[str, Any]
    args: dict[str, Any]
    params: dict[str, Any]

    def group_key(self) -> str:
        return json.dumps(self.args, sort_keys=True, default=str)


def param_fields(params: Any) -> set[str]:
    """Names of the traced hyper-parameters (fields of the Params dataclass)."""
    if not dataclasses.is_dataclass(params):
        return set()
    return {f.name for f in dataclasses.fields(params)}


def expand(spec: SweepSpec | dict[str, Any], kind: Any = None) -> list[Cell]:
    """Every cell of the sweep, each checked before anything runs: settings built, params
    known, numbers, inside their documented ranges; swept keys that are Params fields go to
    ``params``, the rest to ``args``. A swept Params field that the cells' switches leave
    unused everywhere is refused (naming the switch); unused in some cells, it is warned about.
    Params fields may also be fixed in ``args`` (they apply to every cell). ``kind``:
    default the spec's run kind."""
    return expand_built(parse_spec(spec), kind)[0]


def expand_built(spec: SweepSpec, kind: Any = None) -> tuple[list[Cell], dict[str, Any]]:
    """:func:`expand`, and the run built for each group key (``Cell.group_key``)."""
    kind = spec.run_kind if kind is None else kind
    base_args = dict(spec.args)
    seeds = list(spec.seeds)
    settings_names = {f.name for f in dataclasses.fields(kind.settings)}
    for key in base_args:
        if key in RESERVED:
            raise ConfigError(f"sweep args cannot set {key!r} (seeds come from 'seeds', "
                              "outputs go to the sweep folder)")
    base_params = {k: v for k, v in base_args.items() if k not in settings_names}
    base_args = {k: v for k, v in base_args.items() if k in settings_names}
    base = kind.build(kind.make_settings(base_args, where="sweep args: "))
    traced = param_fields(base.params)
    valid = sorted((settings_names - set(RESERVED)) | traced)
    unknown = sorted(set(base_params) - traced)
    if unknown:
        raise ConfigError(f"sweep args: unknown key(s) {unknown}; valid: {', '.join(valid)}")
    built_for: dict[str, Any] = {json.dumps(base_args, sort_keys=True, default=str): base}
    cells = []
    dead_in: dict[str, list[str]] = {}
    swept_in: dict[str, int] = {}
    for index, values in enumerate(settings_list(spec)):
        where = f"sweep cell {index} {json.dumps(values, default=str)}: "
        unknown = sorted(k for k in values if k not in traced and
                         (k not in settings_names or k in RESERVED))
        if unknown:
            raise ConfigError(f"{where}unknown key(s) {unknown}; valid: {', '.join(valid)}")
        params = {**base_params, **{k: v for k, v in values.items() if k in traced}}
        for name, value in params.items():
            try:
                finite = np.isfinite(np.asarray(value, dtype=np.float64)).all()
            except (TypeError, ValueError):
                raise ConfigError(f"{where}{name}={value!r} is not a number") from None
            if not finite:
                raise ConfigError(f"{where}{name}={value!r} is not finite")
        args = {**base_args, **{k: v for k, v in values.items() if k not in traced}}
        settings = kind.make_settings(args, where=where)  # every cell checked before any runs
        key = json.dumps(args, sort_keys=True, default=str)
        if key not in built_for:
            built_for[key] = kind.build(settings)
        built = built_for[key]
        if built.strategy is not None and dataclasses.is_dataclass(built.params):
            cell_params = with_params(built.params, params)
            built.strategy.check_params(cell_params, where=where)
            dead = built.strategy.inactive_params(cell_params)
            for name in values:
                if name in traced:
                    swept_in[name] = swept_in.get(name, 0) + 1
                    if name in dead:
                        dead_in.setdefault(name, []).append(dead[name])
        ident = json.dumps([values, args, seeds, spec.command, spec.kind_ref, base_params],
                           sort_keys=True, default=str)
        digest = hashlib.sha256(ident.encode()).hexdigest()[:8]
        cells.append(Cell(f"c{index:03d}-{digest}", values, args, params))
    for name, switches in dead_in.items():
        if len(switches) == swept_in[name]:
            raise ConfigError(
                f"sweep key {name!r} has no effect in any cell: it acts only with "
                f"{switches[0]} (set that in args or the cells, or drop {name!r})")
        warnings.warn(f"sweep key {name!r} has no effect in {len(switches)} of {swept_in[name]} "
                      f"cells (it acts only with {switches[0]})", stacklevel=3)
    return cells, built_for


def groups_of(cells: list[Cell]) -> list[list[Cell]]:
    """Cells sharing all static settings, in first-seen order (each group = one call)."""
    groups: dict[str, list[Cell]] = {}
    for cell in cells:
        groups.setdefault(cell.group_key(), []).append(cell)
    return list(groups.values())


def with_params(base: Any, overrides: dict[str, Any]) -> Any:
    """``base`` Params with ``overrides``; every field becomes an array of its default's dtype.

    So all cells stack into one batch (booleans stay booleans: 1/0 in a file mean on/off).
    """
    return params_with(base, overrides)
