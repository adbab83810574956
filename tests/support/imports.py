"""The project's imports as its source says them (:mod:`ast`): every ``import`` and ``from … import``
of a file — at module level, inside a function or a method, under ``if TYPE_CHECKING`` — resolved to
the project's modules, and the import circles among them.

A module is a ``.py`` file; a package's ``__init__.py`` is the module named after the package.
Importing ``a.b.c`` runs the packages ``a`` and ``a.b`` first, so for circles an import also reaches
the target's packages that do not contain the importer (their ``__init__`` may import back).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

#: The project's top-level packages (pyproject's ``packages.find``).
PACKAGES = ("app", "robot_io", "session_store")


@dataclass(frozen=True)
class Import:
    """One import of a project module by another, and where it is written."""

    importer: str
    target: str
    where: str  # "path:line", the path relative to the source tree

    def __str__(self) -> str:
        return f"{self.where}: {self.importer} imports {self.target}"


def statements(path: Path) -> Iterator[tuple[str, str, int, int]]:
    """(module, name, level, line) of every import in a file; ``import x.y`` gives (x.y, x.y)."""
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, alias.name, 0, node.lineno
        elif isinstance(node, ast.ImportFrom):
            for alias in node.names:
                yield node.module or "", alias.name, node.level, node.lineno


def project_modules(root: Path, packages: tuple[str, ...] = PACKAGES) -> dict[str, Path]:
    """Module name → file of every module under ``root``'s ``packages``."""
    modules = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _package_of(module: str, path: Path) -> str:
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


def _absolute(module: str, level: int, package: str) -> str:
    """``from .x import y`` in ``package`` → ``package.x`` (``level`` dots)."""
    if not level:
        return module
    base = package.split(".")[:len(package.split(".")) - level + 1]
    return ".".join([*base, module] if module else base)


def _owner(name: str, modules: dict[str, Path]) -> str | None:
    """The project module ``name`` lives in (``a.b.Thing`` → ``a.b``); None: not the project's."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def project_imports(root: Path, packages: tuple[str, ...] = PACKAGES) -> list[Import]:
    """Every import of a project module by another under ``root`` (one per module and line)."""
    modules = project_modules(root, packages)
    found = set()
    for importer, path in modules.items():
        where = str(path.relative_to(root))
        for module, name, level, line in statements(path):
            module = _absolute(module, level, _package_of(importer, path))
            if module.split(".")[0] not in packages:
                continue
            target = _owner(f"{module}.{name}" if module != name else module, modules)
            if target is not None and target != importer:
                found.add(Import(importer, target, f"{where}:{line}"))
    return sorted(found, key=lambda i: (i.where, i.target))


def with_packages(i: Import) -> list[Import]:
    """The import and the target's packages that do not contain the importer (they run first)."""
    parts = i.target.split(".")
    packages = [".".join(parts[:n]) for n in range(1, len(parts))]
    return [Import(i.importer, p, i.where) for p in packages
            if not (i.importer + ".").startswith(p + ".")] + [i]


def circles(imports: list[Import]) -> list[list[Import]]:
    """The import circles: for each strongly connected set of modules (Tarjan), the imports
    between its members, the packages an import runs included."""
    imports = [reached for i in imports for reached in with_packages(i)]
    graph: dict[str, set[str]] = {}
    for i in imports:
        graph.setdefault(i.importer, set()).add(i.target)
        graph.setdefault(i.target, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[set[str]] = []

    def visit(v: str) -> None:  # recursion depth ≤ the number of modules (a few hundred)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [[i for i in imports if i.importer in c and i.target in c] for c in components]
