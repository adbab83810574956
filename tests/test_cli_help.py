"""``handover --help`` says what the tool does and how a lab starts; ``--version`` names the
installed version; no help text carries reST or Markdown markup (``x``, :class:`x`, `x`), which a
terminal prints as it is."""

from __future__ import annotations

import argparse
import re
from importlib.metadata import version

import pytest

from app.cli import build_parser, main

#: Markup of docstrings and Markdown that a terminal shows literally.
MARKUP = re.compile(r"``|:[a-z]+:`|`[^`\n]+`")


def helps(capsys: pytest.CaptureFixture[str], *command: str) -> str:
    """What ``handover [COMMAND] --help`` prints (it exits 0)."""
    with pytest.raises(SystemExit) as exited:
        main([*command, "--help"])
    assert exited.value.code == 0, command
    return capsys.readouterr().out


def commands() -> list[str]:
    subparsers = next(action for action in build_parser()._actions
                      if isinstance(action, argparse._SubParsersAction))
    return sorted(subparsers.choices)


def test_the_help_says_what_the_tool_does_and_how_a_lab_starts(capsys):
    text = helps(capsys)
    assert text.split("\n\n")[1].startswith(
        "handover-lab: adaptive robot-to-human handovers for human-robot interaction\nstudies.")
    assert "registers its own subcommands" not in text
    start = text[text.index("to start:"):]
    for command in ("handover serve --study ./study", "handover check-devices --config lab.toml",
                    "handover report ./study --out ./report"):
        assert command in start, start


def test_version_names_the_installed_version(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["--version"])
    assert exited.value.code == 0
    assert capsys.readouterr().out == f"handover {version('handover-lab')}\n"


def test_no_help_text_carries_markup(capsys):
    assert {"serve", "report", "export", "benchmark-pl"} <= set(commands())
    found = {}
    for command in ["", *commands()]:
        text = helps(capsys, *([command] if command else []))
        if hits := MARKUP.findall(text):
            found[command or "handover"] = hits
    assert not found, found


@pytest.mark.parametrize("command", ["serve", "run-session", "simulate-trial"])
def test_the_scenario_option_lists_its_values(capsys, command):
    """``serve --help`` did not say what --scenario takes (issue 45, item 18)."""
    assert "--scenario {straightforward,perturbed}" in " ".join(helps(capsys, command).split())
