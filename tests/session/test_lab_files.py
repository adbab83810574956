"""Every ``lab.toml`` the docs, the README and the tests' support write still loads: each
```toml block of ``docs/*.md`` and ``README.md`` (a block of a few tables, as a lab pastes it into
the full example of docs/hardware.md), and the files the support modules write for a stand-in
tracker or UR."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from types import SimpleNamespace

import pytest
from support.engine import BRIEF_PROTOCOL, SHORT_PROTOCOL, protocol_toml
from support.frozen import lab_toml
from support.natnet import natnet_toml
from support.vicon import vicon_toml

from app.session.config import LabConfig, load_lab_config

ROOT = Path(__file__).resolve().parents[2]
BLOCK = re.compile(r"^```toml\n(.*?)^```", re.MULTILINE | re.DOTALL)


def documented_blocks() -> list[tuple[str, str]]:
    """(where, text) of every ```toml block in the user docs and the README."""
    blocks = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for number, match in enumerate(BLOCK.finditer(doc.read_text()), start=1):
            blocks.append((f"{doc.relative_to(ROOT)} block {number}", match.group(1)))
    return blocks


SUPPORT_FILES = [
    ("support.natnet.natnet_toml", natnet_toml(SimpleNamespace(address=("127.0.0.1", 1510)))),
    ("support.vicon.vicon_toml", vicon_toml()),
    ("support.frozen.lab_toml", lab_toml("127.0.0.9")),
    ("support.engine short protocol", f"[protocol]\n{protocol_toml(SHORT_PROTOCOL)}"),
    ("support.engine brief protocol", f"[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}"),
]


def test_the_docs_have_lab_files_with_a_hand_source_of_each_tracker_they_describe():
    texts = "\n".join(text for _, text in documented_blocks())
    for kind in ("lsl", "natnet", "vicon"):
        assert f'kind = "{kind}"' in texts


#: The full example of docs/hardware.md, into which a block of a few tables is pasted.
FULL_EXAMPLE = "# lab.toml:"


def is_whole_file(text: str) -> bool:
    """A block that names the arm is a whole file; the others are a few tables to paste."""
    return "[arm]" in text


@pytest.mark.parametrize("text", [pytest.param(text, id=where) for where, text in documented_blocks()])
def test_every_lab_file_of_the_docs_loads(tmp_path, text):
    lab = tmp_path / "lab.toml"
    lab.write_text(text)
    if is_whole_file(text):
        load_lab_config(lab)
    else:
        full = next(block for _, block in documented_blocks() if block.startswith(FULL_EXAMPLE))
        LabConfig.model_validate(tomllib.loads(full) | tomllib.loads(text))


@pytest.mark.parametrize("text", [pytest.param(text, id=where) for where, text in SUPPORT_FILES])
def test_every_lab_file_the_tests_write_loads(tmp_path, text):
    lab = tmp_path / "lab.toml"
    lab.write_text(text)
    load_lab_config(lab)
