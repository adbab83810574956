"""``handover check-devices`` and ``load_lab_config`` on a ``lab.toml`` written by the test."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pydantic import ValidationError

from app.cli import main
from app.session.config import load_lab_config


def check_devices(folder: Path, capsys, toml: str) -> tuple[int, str]:
    """``handover check-devices`` on a ``lab.toml`` of ``toml``: its exit code and its output."""
    lab = folder / "lab.toml"
    lab.write_text(toml)
    code = main(["check-devices", "--config", str(lab)])
    return code, capsys.readouterr().out


def hand_line(out: str) -> str:
    """The line ``check-devices`` prints on the hand source."""
    return next(line for line in out.splitlines() if line.startswith("hand:"))


def assert_hand_source_refused(folder: Path, capsys, text: str, message: str) -> None:
    """A ``[hand_source]`` table of ``text`` is refused with ``message`` when read, and
    ``check-devices`` refuses it before anything is opened (exit 2)."""
    lab = folder / "lab.toml"
    lab.write_text(f"[hand_source]\n{text}")
    with pytest.raises(ValidationError, match=re.escape(message)):
        load_lab_config(lab)
    assert main(["check-devices", "--config", str(lab)]) == 2
    assert message in capsys.readouterr().err
