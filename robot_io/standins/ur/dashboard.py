"""The dashboard server (port 29999): one line in, one line out, as PolyScope answers.

Enough of it for ur_rtde's ``DashboardClient`` and ``RTDEControlInterface``: robotmode, safetymode,
safetystatus, unlock protective stop (refused within 5 s of the stop), close (safety) popup, play,
stop, pause, running, programState, PolyscopeVersion, is in remote control, get robot model,
get serial number, power on/off, brake release, addToLog, quit.
"""

from __future__ import annotations

import socket

from robot_io.standins.ur.listener import read_lines
from robot_io.standins.ur.model import Controller, Safety, Series

WELCOME = "Connected: Universal Robots Dashboard Server"
POLYSCOPE = {Series.CB3: "URSoftware 3.15.7.106331 (Jul 09 2021)",
             Series.E_SERIES: "URSoftware 5.11.1.108318 (Mar 22 2022)"}


def reply(controller: Controller, command: str) -> str:
    """The dashboard's answer to one command line."""
    word = command.strip()
    lower = word.lower()
    with controller.lock:
        program = controller.program
        running = program is not None
        fixed = {
            "robotmode": "Robotmode: RUNNING",
            "safetymode": f"Safetymode: {controller.safety.name}",
            "safetystatus": f"Safetystatus: {controller.safety.name}",
            "running": f"Program running: {str(running).lower()}",
            "programstate": f"{'PLAYING' if running else 'STOPPED'} "
                            f"{program.name if program is not None else '<unnamed>'}",
            "polyscopeversion": POLYSCOPE[controller.series],
            "is in remote control": "true",
            "get robot model": "UR5",
            "get serial number": "20185500001",
            "close popup": "closing popup",
            "close safety popup": "closing safety popup",
            "power on": "Powering on",
            "power off": "Powering off",
            "brake release": "Brake releasing",
            "quit": "Disconnected",
            "get loaded program": "No program loaded",
        }
        if lower in fixed:
            return fixed[lower]
        if lower == "unlock protective stop":
            return controller.unlock_protective_stop()
        if lower == "stop":  # a controller says "Stopped" also when nothing was running
            controller.end_program("dashboard stop")
            return "Stopped"
        if lower == "pause":
            return "Failed to execute: pause" if not running else "Pausing program"
        if lower == "play":
            return "Failed to execute: play"  # the stand-in has no loaded .urp to play
        if lower.startswith("addtolog "):
            controller.event(f"log: {word[9:]}")
            return "Added log message"
        if lower.startswith("popup "):
            return "showing popup"
        if controller.safety is not Safety.NORMAL and lower == "restart safety":
            controller.safety = Safety.NORMAL
            return "Restarting safety"
    return f"could not understand: '{word}'"


def serve(controller: Controller, sock: socket.socket) -> None:
    sock.sendall((WELCOME + "\n").encode())
    for line in read_lines(sock):
        answer = reply(controller, line)
        sock.sendall((answer + "\n").encode())
        if answer == "Disconnected":
            return
