"""The docs are current: the sweep-format reference lists exactly the settings the code has;
every row of the bad-inputs table names tests that exist."""

import importlib.util
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_sweep_reference_is_current():
    spec = importlib.util.spec_from_file_location("generate", DOCS / "generate.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert gen.generated() in (DOCS / "sweeps.md").read_text(), "run `make docs`"


def _held_by_cells() -> list[tuple[str, str]]:
    """(tried, held by) of every row of docs/bad_inputs.md's table."""
    import re

    rows, in_table = [], False
    for line in (DOCS / "bad_inputs.md").read_text().splitlines():
        if line.startswith("| tried |"):
            assert line == "| tried | via | what it gets now | held by |", line
            in_table = True
            continue
        if not in_table or not line.startswith("|") or line.startswith("|---"):
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]  # '\|' is text
        assert len(cells) == 4, f"{len(cells)} columns, not 4: {line[:120]}"
        rows.append((cells[0], cells[3]))
    return rows


def test_bad_inputs_rows_name_tests_that_exist():
    """Every row of docs/bad_inputs.md names the test(s) holding it (or says none), and each
    named test exists: a renamed or removed test fails here until the doc is regenerated."""
    import ast
    import re

    rows = _held_by_cells()
    assert len(rows) > 100
    defined: dict[Path, set[str]] = {}
    for tried, cell in rows:
        if cell == "none":
            continue
        ids = re.findall(r"`([^`]+)`", cell)
        assert ids and re.sub(r"`[^`]+`", "", cell).strip(", ") == "", (tried, cell)
        for node_id in ids:
            path, _, name = node_id.partition("::")
            name = name.split("[", 1)[0].split("::")[-1]  # test_x[param], Class::test_x
            file = DOCS.parent / path
            assert path.startswith("tests/") and file.is_file(), (tried, node_id)
            if file not in defined:
                tree = ast.parse(file.read_text())
                defined[file] = {n.name for n in ast.walk(tree)
                                 if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)}
            assert name.startswith("test_") and name in defined[file], (tried, node_id)
