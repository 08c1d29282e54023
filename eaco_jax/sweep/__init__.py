"""Hyper-parameter sweeps over a run kind: grid, listed or random settings x seeds.

Swept keys that are fields of the strategy's Params are *traced*: cells that differ only in
them share one compiled program and run as ONE vmapped call over stacked params x seeds. Any
other key is a run setting (``ants``, ``problem``, budget, ...): cells with different settings
run one group after another (or one Ray task per cell). Files: ``OUT/cells/*.json`` (a rerun
skips finished cells), ``OUT/table.csv`` / ``table.json``, ``OUT/summary.json`` and
``OUT/summary.png``. The file format: :mod:`eaco_jax.sweep.spec` and ``docs/sweeps.md``.
"""

from eaco_jax.sweep.cells import Cell, expand, groups_of, with_params
from eaco_jax.sweep.local import plan, run_group
from eaco_jax.sweep.runner import run_sweep
from eaco_jax.sweep.spec import SweepSpec, load_spec, parse_spec

#: an alias of :func:`parse_spec`
validate_spec = parse_spec

__all__ = ["Cell", "SweepSpec", "expand", "groups_of", "load_spec", "parse_spec", "plan",
           "run_group", "run_sweep", "validate_spec", "with_params"]
