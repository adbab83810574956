"""The whole tree's layers: no import circles, and no module imports one of a higher layer — across the
packages and inside each of them, between its rooms (app's subpackages, robot_io's device rooms and
controller, session_store's modules).

Every import counts, at module level, inside a function or under ``if TYPE_CHECKING``
(:mod:`support.imports`): an import hidden in a function is still a dependency, only a later one.
"""

from __future__ import annotations

from pathlib import Path

import pytest
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

#: The rooms inside each package, from the bottom up, as :data:`LAYERS` is for the tree (app's rooms
#: are its layers there). robot_io: the errors; the plain values (bounds, vectors, θ, the clock,
#: the child processes' signals, the minimum-jerk demonstration); the scene and the device kinds'
#: pattern; the device rooms (a gripper knows the arm it hangs on); the configuration that
#: assembles them; the controller; the devices opened from the configuration; the rig process; the
#: stand-ins that play a lab's devices.
#: session_store: from its errors and vocabulary up to the export that reads everything.
ROOMS: dict[str, tuple[tuple[str, ...], ...]] = {
    "app": LAYERS,
    "robot_io": (
        ("robot_io.errors",),
        ("robot_io.bounds", "robot_io.vector", "robot_io.theta", "robot_io.clock",
         "robot_io.child_signals", "robot_io.minimum_jerk", "robot_io.lsl_log"),
        ("robot_io.scene", "robot_io.kinds"),
        ("robot_io.hands", "robot_io.arms"),
        ("robot_io.grippers",),
        ("robot_io.config",),
        ("robot_io.control",),
        ("robot_io.devices",),
        ("robot_io.rig", "robot_io.plot"),
        ("robot_io.standins",),
        ("robot_io",),
    ),
    "session_store": (
        ("session_store.errors", "session_store.vocabulary", "session_store.database"),
        ("session_store.paths", "session_store.lock"),
        ("session_store.models", "session_store.file_check"),
        ("session_store.schema", "session_store.catalog"),
        ("session_store.store", "session_store.integrity"),
        ("session_store.read_only_copy",),
        ("session_store.export",),
        ("session_store",),
    ),
}


def part(module: str, layers: tuple[tuple[str, ...], ...] = LAYERS) -> str:
    """The part of ``layers`` a module belongs to (the longest entry it is in)."""
    parts = [p for layer in layers for p in layer if module == p or module.startswith(p + ".")]
    if not parts:
        raise AssertionError(f"{module} is in no layer of {[p for layer in layers for p in layer]}")
    return max(parts, key=len)


def layer(module: str, layers: tuple[tuple[str, ...], ...] = LAYERS) -> int:
    return next(n for n, names in enumerate(layers) if part(module, layers) in names)


def upward(imports: list[Import], layers: tuple[tuple[str, ...], ...] = LAYERS) -> list[Import]:
    """The imports of a module of another part that is not below the importer's."""
    return [i for i in imports if part(i.importer, layers) != part(i.target, layers)
            and layer(i.target, layers) >= layer(i.importer, layers)]


def inside(package: str, imports: list[Import]) -> list[Import]:
    """The imports between two modules of ``package``."""
    return [i for i in imports if i.importer.split(".")[0] == package == i.target.split(".")[0]]


def report(found: list[Import]) -> str:
    return "\n".join(str(i) for i in found)


def test_every_module_is_in_a_layer():
    modules = project_modules(ROOT)
    assert len(modules) > 150
    assert {part(m) for m in modules} == {p for names in LAYERS for p in names}


def test_no_module_imports_a_higher_layer():
    found = upward(project_imports(ROOT))
    assert found == [], "imports of a higher layer:\n" + report(found)


@pytest.mark.parametrize("package", list(ROOMS))
def test_every_module_of_a_package_is_in_one_of_its_rooms(package: str):
    modules = [m for m in project_modules(ROOT) if m.split(".")[0] == package]
    rooms = {part(m, ROOMS[package]) for m in modules}
    assert rooms == {p for names in ROOMS[package] for p in names if p.split(".")[0] == package}


@pytest.mark.parametrize("package", list(ROOMS))
def test_no_room_imports_a_higher_room(package: str):
    found = upward(inside(package, project_imports(ROOT)), ROOMS[package])
    assert found == [], f"imports of a higher room of {package}:\n" + report(found)


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
