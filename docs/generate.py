"""Regenerate docs/sweeps.md's tables from the code (``make docs``); tests/test_docs.py checks
that the committed file is current."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

DOC = Path(__file__).with_name("sweeps.md")
BEGIN, END = "<!-- generated: settings -->", "<!-- end generated -->"


def generated() -> str:
    from eaco_jax.runs import kinds
    from eaco_jax.runs.base import settings_table
    from eaco_jax.strategies import ContinuousEACO, GraphEACO, PathEACO

    def params(strategy: object, runs: str) -> str:
        defaults = strategy.default_params(None)
        ranges = getattr(type(defaults), "RANGES", {})
        dead = strategy.inactive_params(defaults)
        rows = [f"| `{type(defaults).__name__}` ({runs}) | default | range | acts only with |",
                "|---|---|---|---|"]
        for f in dataclasses.fields(defaults):
            value = getattr(type(defaults), f.name, f.default)
            rows.append(f"| `{f.name}` | `{value!r}` | {ranges.get(f.name, '')} | "
                        f"{dead.get(f.name, '')} |")
        return "\n".join(rows)

    tables = "\n\n".join(settings_table(k) for k in kinds().values())
    graph = params(GraphEACO(), "tsp")
    continuous = params(ContinuousEACO(), "constrained, gait")
    path = params(PathEACO(), "path")
    return f"""{BEGIN}
## Settings of each run kind

{tables}

## Traced hyper-parameters: defaults and ranges

Checked on the host before a run (API, `--params`, every sweep cell); a value outside its range
is one line naming the field, the value, the range and the cell. "acts only with": under the
default switches the field has no effect, and sweeping it is refused unless that switch is on
(`GraphEACO`'s column is for the with-2-opt defaults; without local search the MMAS defaults
change `rho`, `alpha_g`, `branching`, `restart_after`, `restart_branching`,
`use_restart_best` and `gb_every`).

{graph}

{continuous}

{path}
{END}"""


def main() -> None:
    text = DOC.read_text()
    pattern = re.compile(re.escape(BEGIN) + ".*?" + re.escape(END), re.S)
    DOC.write_text(pattern.sub(lambda _: generated(), text))


if __name__ == "__main__":
    main()
