"""The package's layers import only downwards, and no modules import each other in a loop.

Layers (ARCHITECTURE.md): foundation <- ops, gait (with the robot spec loader) <- problems <-
strategies <- driver <- runs <- sweep <- cli. Every import counts, also one inside a function.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "eaco_jax"

#: module prefix -> layer (the longest matching prefix decides)
LAYERS = {
    "eaco_jax._version": 0, "eaco_jax.errors": 0, "eaco_jax.outputs": 0, "eaco_jax.plots": 0,
    "eaco_jax.ops": 1, "eaco_jax.gait": 1,
    "eaco_jax.problems": 2,
    "eaco_jax.strategies": 3,
    "eaco_jax.driver": 4,
    "eaco_jax": 5,  # the package's facade (__init__): ea.minimize, ea.problems, ...
    "eaco_jax.runs": 6,
    "eaco_jax.sweep": 7,
    "eaco_jax.cli": 8,
    "eaco_jax.__main__": 8,  # `python -m eaco_jax` runs the command line
}


def layer(module: str) -> int:
    best = max((p for p in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return LAYERS[best]


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(path: Path) -> set[str]:
    """Every eaco_jax module ``path`` imports (module level or inside functions)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("eaco_jax")}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.startswith("eaco_jax"):
                for a in node.names:  # `from eaco_jax.x import y`: y may be a module
                    sub = f"{node.module}.{a.name}"
                    out.add(sub if _is_module(sub) else node.module)
    return out


def _is_module(name: str) -> bool:
    rel = Path(*name.split("."))
    return (ROOT / rel).with_suffix(".py").exists() or (ROOT / rel / "__init__.py").exists()


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


@pytest.mark.parametrize("name", sorted(n for n in MODULES if n != "eaco_jax"))
def test_imports_point_down(name):
    upward = sorted(m for m in imports(MODULES[name]) if layer(m) > layer(name))
    assert not upward, f"{name} (layer {layer(name)}) imports higher layers: {upward}"


def test_no_import_cycles():
    graph = {n: {m for m in imports(p) if m in MODULES and m != n} for n, p in MODULES.items()}
    graph.pop("eaco_jax")  # the facade re-exports; it is imported by nothing below it
    for deps in graph.values():
        deps.discard("eaco_jax")
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                cycle = stack[stack.index(m):] + [m]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)


def test_the_rule_can_fail():
    """The checker sees an upward import when there is one."""
    assert layer("eaco_jax.cli.runs") > layer("eaco_jax.runs.tsp") > layer("eaco_jax.driver.stop")
    assert "eaco_jax.runs.base" in imports(PACKAGE / "cli" / "runs.py")
