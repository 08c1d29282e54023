"""The sweep-format reference lists exactly the settings the code has."""

import importlib.util
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_sweep_reference_is_current():
    spec = importlib.util.spec_from_file_location("generate", DOCS / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert gen.generated() in (DOCS / "sweeps.md").read_text(), "run `make docs`"
