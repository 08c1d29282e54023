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

    def params(cls: type) -> str:
        return ", ".join(f"`{f.name}`" for f in dataclasses.fields(cls().default_params(None)))

    tables = "\n\n".join(settings_table(k) for k in kinds().values())
    return f"""{BEGIN}
## Settings of each run kind

{tables}

## Traced hyper-parameters

| strategy (run kinds) | Params fields |
|---|---|
| `GraphEACO` (tsp) | {params(GraphEACO)} |
| `ContinuousEACO` (constrained, gait) | {params(ContinuousEACO)} |
| `PathEACO` (path) | {params(PathEACO)} |
{END}"""


def main() -> None:
    text = DOC.read_text()
    pattern = re.compile(re.escape(BEGIN) + ".*?" + re.escape(END), re.S)
    DOC.write_text(pattern.sub(lambda _: generated(), text))


if __name__ == "__main__":
    main()
