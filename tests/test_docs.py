"""The user docs hold for a newcomer: they refer to nothing outside the project (a clone has no
``../shared`` folder and no DESIGN.md), and the options table of ``handover serve`` in
docs/running-a-study.md names exactly the options serve accepts."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from app.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
#: What a clone of the project does not have.
OUTSIDE = re.compile(r"\.\./shared|shared/reference|DESIGN\.md")


def test_nothing_refers_outside_the_project():
    files = [ROOT / "README.md", *(ROOT / "docs").glob("*.md"),
             *(path for package in ("app", "robot_io", "session_store")
               for path in (ROOT / package).rglob("*.py"))]
    found = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}" for path in files
             for number, line in enumerate(path.read_text().splitlines(), 1)
             if OUTSIDE.search(line)]
    assert len(files) > 50 and not found, "\n".join(found)


def test_the_serve_options_table_names_every_option_serve_has():
    subparsers = next(action for action in build_parser()._actions
                      if isinstance(action, argparse._SubParsersAction))
    accepted = {option for action in subparsers.choices["serve"]._actions
                for option in action.option_strings if option.startswith("--")} - {"--help"}
    text = (ROOT / "docs" / "running-a-study.md").read_text()
    table = text[text.index("| option | meaning |"):]
    table = table[:table.index("\n\n")]
    documented = set(re.findall(r"--[a-z][a-z-]*", table))
    assert documented == accepted, (f"documented, not accepted: {sorted(documented - accepted)}; "
                                    f"accepted, not documented: {sorted(accepted - documented)}")


def cycle_rows() -> list[str]:
    """The handover cycle's table (robot_io.control.stages) as docs/controller.md shows it."""
    from robot_io.control.stages import PAPER_CYCLE

    return [f"| `{row.name}` | {row.part.value.replace('_', ' ')} | {row.entry} | "
            f"{row.gate.button if row.gate else ''} | {row.does} | {row.exit} |"
            for row in PAPER_CYCLE.rows]


def test_the_cycle_table_in_the_docs_is_the_one_the_rig_runs():
    text = (ROOT / "docs" / "controller.md").read_text()
    table = text[text.index("| stage | part | begins when | gate | the rig | ends when |"):]
    rows = table[:table.index("\n\n")].splitlines()[2:]
    assert rows == cycle_rows(), "\n".join(["docs/controller.md's cycle table should read:",
                                            *cycle_rows()])


def test_the_configuration_block_of_the_controller_page_shows_the_defaults():
    """docs/controller.md says "keys that are left out take the defaults below", and showed
    `realtime_priority = false` where the default is "auto" (issue 45, item 19): every key of its
    block is the value a lab.toml without it gets."""
    import tomllib

    from app.session.config import LabConfig

    text = (ROOT / "docs" / "controller.md").read_text()
    section = text[text.index("## Configuration"):]
    block = section[section.index("```toml\n") + len("```toml\n"):]
    block = block[:block.index("\n```")]
    documented = tomllib.loads(block)
    defaults = LabConfig().model_dump(mode="json")
    wrong = [f"[{table}] {key} = {value!r}, the default is {defaults[table][key]!r}"
             for table, keys in documented.items() for key, value in keys.items()
             if defaults[table][key] != value]
    assert len(documented) >= 8 and not wrong, "\n".join(wrong)


def test_no_page_says_a_resumed_rehearsal_needs_a_rig_change():
    """docs/running-a-study.md and docs/protocol.md said a rehearsed session always needs the rig
    change confirmed when resumed (issue 45, item 19); it resumes in a new rehearsal without one
    (tests/session/test_rehearsal.py, test_a_rehearsed_session_resumes_in_a_new_rehearsal_without_a_
    rig_change), as docs/hardware.md says."""
    sentences = [(path.name, " ".join(sentence.split())) for path in (ROOT / "docs").glob("*.md")
                 for sentence in re.split(r"(?<=[.;:])\s", path.read_text())]
    claims = [f"{name}: {sentence}" for name, sentence in sentences
              if "rehears" in sentence and re.search(r"always needs?\b", sentence)]
    assert not claims, "\n".join(claims)
