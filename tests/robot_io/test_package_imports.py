"""``robot_io`` stands on its own: no module of it imports the application (``app``), at the top or
inside a function, and its modules import one another without a circle (a circle held together only
by an import inside a function or under TYPE_CHECKING included)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2] / "robot_io"


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path) -> set[str]:
    """Every module ``path`` imports, wherever the import stands (absolute names)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


GRAPH = {module_name(path): imported(path) for path in ROOT.rglob("*.py")}


def test_no_module_of_robot_io_imports_the_application():
    upward = {module: sorted(name for name in names if name == "app" or name.startswith("app."))
              for module, names in GRAPH.items()}
    assert {module: names for module, names in upward.items() if names} == {}


def test_the_modules_of_robot_io_import_one_another_without_a_circle():
    edges = {module: {name for name in names if name in GRAPH and name != module}
             for module, names in GRAPH.items()}
    circles, done = [], set()

    def visit(module: str, path: list[str]) -> None:
        if module in path:
            circles.append([*path[path.index(module):], module])
            return
        if module in done:
            return
        for other in sorted(edges[module]):
            visit(other, [*path, module])
        done.add(module)

    for module in sorted(edges):
        visit(module, [])
    assert circles == []
