"""The whole tree's layers: no import circles, and no module imports one of a higher layer.

Every import counts, at module level, inside a function or under ``if TYPE_CHECKING``
(:mod:`support.imports`): an import hidden in a function is still a dependency, only a later one.
"""

from __future__ import annotations

from pathlib import Path

from support.imports import Import, circles, project_imports, project_modules

ROOT = Path(__file__).resolve().parents[1]

#: The layers from the bottom up; a module imports from its own part of the tree or from a lower
#: layer. Parts in one layer know nothing of each other. robot_io (the controller) knows no study;
#: the store records the study's words; the learner knows θ only; ``app.arguments`` parses the
#: commands' values for every command's module; the protocol runs a study on the
#: learner and the store; the session (serve, run-session) and the report use the protocol; the
#: tablet and dashboard show a session; ``app.cli`` (and the ``app`` package) assembles the command.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("robot_io",),
    ("session_store", "app.learning", "app.arguments"),
    ("app.protocol",),
    ("app.session", "app.analysis"),
    ("app.ui",),
    ("app.cli", "app"),
)

def part(module: str) -> str:
    """The part of the tree a module belongs to (the longest entry of :data:`LAYERS` it is in)."""
    parts = [p for layer in LAYERS for p in layer if module == p or module.startswith(p + ".")]
    if not parts:
        raise AssertionError(f"{module} is in no layer of LAYERS")
    return max(parts, key=len)


def layer(module: str) -> int:
    return next(n for n, names in enumerate(LAYERS) if part(module) in names)


def upward(imports: list[Import]) -> list[Import]:
    """The imports of a module of another part that is not below the importer's."""
    return [i for i in imports if part(i.importer) != part(i.target)
            and layer(i.target) >= layer(i.importer)]


def report(found: list[Import]) -> str:
    return "\n".join(str(i) for i in found)


def test_every_module_is_in_a_layer():
    modules = project_modules(ROOT)
    assert len(modules) > 150
    assert {part(m) for m in modules} == {p for names in LAYERS for p in names}


def test_no_module_imports_a_higher_layer():
    found = upward(project_imports(ROOT))
    assert found == [], "imports of a higher layer:\n" + report(found)


def test_no_import_circles():
    found = circles(project_imports(ROOT))
    assert found == [], "import circles:\n" + "\n\n".join(report(c) for c in found)


def test_imports_in_functions_and_type_checking_blocks_count(tmp_path: Path):
    package = tmp_path / "app"
    (package / "inner").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "inner" / "__init__.py").write_text("from app.inner import a\n")
    (package / "inner" / "a.py").write_text(
        "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from app.b import Thing\n")
    (package / "b.py").write_text("def f():\n    from .inner.a import g\n")
    imports = project_imports(tmp_path, ("app",))
    assert [str(i) for i in imports] == [
        "app/b.py:2: app.b imports app.inner.a",
        "app/inner/__init__.py:1: app.inner imports app.inner.a",
        "app/inner/a.py:4: app.inner.a imports app.b"]
    assert [sorted(str(i) for i in c) for c in circles(imports)] == [[
        "app/b.py:2: app.b imports app.inner", "app/b.py:2: app.b imports app.inner.a",
        "app/inner/__init__.py:1: app.inner imports app.inner.a",
        "app/inner/a.py:4: app.inner.a imports app.b"]]
    assert upward(imports) == []  # all of it is the top layer's "app"
