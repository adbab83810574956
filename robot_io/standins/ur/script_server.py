"""The script ports (30001–30003): programs arrive as URScript text and start running when complete.

Nothing of URScript is interpreted. A program is the text from a top-level ``def name():`` or
``sec name():`` line to the top-level ``end`` line. ``rtde_control`` — ur_rtde's control script — runs
as :class:`~robot_io.standins.ur.control_script.ControlScript` with the register offset it was uploaded
with; any other program is recorded and "finishes" at once.
"""

from __future__ import annotations

import re
import socket

from robot_io.standins.ur.control_script import ControlScript
from robot_io.standins.ur.listener import read_lines
from robot_io.standins.ur.model import Controller

PORTS = (30001, 30002, 30003)
_HEADER = re.compile(r"^(def|sec)\s+(\w+)\s*\(\s*\)\s*:")
_OFFSET = re.compile(r"reg_offset_int\s*=\s*(?:#[^\n]*\n\s*)?(\d+)")


class FinishedProgram:
    """A program the stand-in does not model: it ends on its first cycle."""

    def __init__(self, name: str) -> None:
        self.name = name

    def step(self, controller: Controller, dt: float) -> bool:
        return False


def program_for(text: str, name: str) -> ControlScript | FinishedProgram:
    """What the stand-in runs for a complete program text."""
    if name != ControlScript.name:
        return FinishedProgram(name)
    match = _OFFSET.search(text)
    if match is None:
        raise ValueError("rtde_control script without a register offset (reg_offset_int)")
    return ControlScript(int(match.group(1)))


def serve(controller: Controller, sock: socket.socket) -> None:
    lines: list[str] = []
    name = None
    for line in read_lines(sock):
        header = _HEADER.match(line)
        if name is None and header:
            name, lines = header.group(2), [line]
        elif name is not None:
            lines.append(line)
            if line.strip() == "end" and not line.startswith((" ", "\t")):
                text = "\n".join(lines) + "\n"
                with controller.lock:
                    controller.last_script = text
                    controller.start_program(program_for(text, name))
                name = None
        elif line.strip():
            with controller.lock:
                controller.event(f"script line outside a program: {line.strip()[:80]}")
