"""The stand-in's control port: JSON lines for tests and dry runs (fault injection, what was received).

Each request is one JSON object with ``"op"``; each reply one JSON object (``{"ok": true, ...}``, or
``{"ok": false, "error": ...}``). Operations:

``ping``; ``state`` (pose, joint angles q, force, safety, program, tool outputs, the last 50 events,
the longest gap between two cycles);
``events`` (all of them); ``received`` (every command
data package: ``[t, command id, doubles]``, ``t`` in the stand-in's ``time.monotonic``);
``protective_stop``; ``emergency_stop``; ``release_emergency_stop``; ``drop_sockets`` (close every
client connection on every port); ``clients`` (how many client connections each port has open, by
port number: what a client's close left behind); ``stall`` with ``seconds`` (no cycles, no output packages);
``lag_readers`` with ``seconds`` (the clients that only read, such as RTDEReceiveInterface, get
every package that late: a loaded host);
``set_force`` with ``force`` (6 values, N and N·m); ``set_pose`` with ``pose`` (6 values);
``set_hand`` with ``position`` (3 values, or null) and ``configure_pull`` with ``direction``,
``pull_n``, ``grasp_delay_s``, ``tool_output``, ``open_level`` and optionally ``gripper``
(``"tool_output"``, the default, or ``"robotiq_socket"``: which gripper holds the object) — the
rehearsal's simulated pull; ``configure_robotiq`` with any of ``object_position`` (finger position
0–255 where the object stops the closing fingers, or null: no object), ``fault`` (what ``GET FLT``
answers) and ``answering`` (false: the URCap socket answers nothing).
"""

from __future__ import annotations

import dataclasses
import json
import socket
import time
from collections.abc import Sequence

import numpy as np

from robot_io.hands.simulated_pull import SimulatedPull
from robot_io.standins.ur.listener import Listener, read_lines
from robot_io.standins.ur.model import Controller

DEFAULT_PORT = 30100


def handle(controller: Controller, request: dict, ports: Sequence[Listener]) -> dict:
    """The answer to one request; ``ports``: the client ports' listeners (not the control port's)."""
    op = request.get("op")
    with controller.lock:
        if op == "ping":
            return {"ok": True, "series": int(controller.series)}
        if op == "state":
            program = controller.program
            return {"ok": True, "pose": list(controller.arm.pose), "q": list(controller.arm.joints()),
                    "force": list(controller.force), "safety": controller.safety.name,
                    "program": program and program.name, "tool_outputs": controller.tool_outputs,
                    "robotiq": dataclasses.asdict(controller.robotiq),
                    "events": controller.events[-50:],
                    "speed": float(np.linalg.norm(controller.arm.velocity)),
                    "stalled": time.monotonic() < controller.stalled_until,
                    "longest_gap_s": controller.longest_gap_s}
        if op == "events":
            return {"ok": True, "events": list(controller.events)}
        if op == "received":
            return {"ok": True, "received": [[r.t, r.command, r.values] for r in controller.received]}
        if op == "protective_stop":
            controller.protective_stop("injected by the control port")
            return {"ok": True}
        if op == "emergency_stop":
            controller.emergency_stop("injected by the control port")
            return {"ok": True}
        if op == "release_emergency_stop":
            controller.release_emergency_stop()
            return {"ok": True}
        if op == "stall":
            controller.stalled_until = time.monotonic() + float(request["seconds"])
            controller.event(f"stalling for {request['seconds']} s")
            return {"ok": True}
        if op == "lag_readers":
            controller.reader_lag_s = float(request["seconds"])
            controller.event(f"readers' packages {request['seconds']} s late")
            return {"ok": True}
        if op == "set_force":
            controller.force = np.asarray(request["force"], dtype=float).reshape(6)
            return {"ok": True}
        if op == "set_hand":
            hand = request["position"]
            controller.hand = None if hand is None else np.asarray(hand, dtype=float).reshape(3)
            return {"ok": True}
        if op == "configure_pull":
            controller.pull = SimulatedPull(np.asarray(request["direction"], dtype=float),
                                            float(request["pull_n"]),
                                            float(request["grasp_delay_s"]))
            controller.pull_output = int(request["tool_output"])
            controller.pull_open_level = bool(request["open_level"])
            controller.pull_gripper = request.get("gripper", "tool_output")
            controller.event(f"simulated pull of {request['pull_n']} N configured")
            return {"ok": True}
        if op == "configure_robotiq":
            robotiq, changed = controller.robotiq, {}
            for key in ("object_position", "fault", "answering"):
                if key in request:
                    setattr(robotiq, key, request[key])
                    changed[key] = request[key]
            controller.event(f"robotiq configured: {changed}")
            return {"ok": True}
        if op == "set_pose":
            controller.arm.pose = np.asarray(request["pose"], dtype=float).reshape(6)
            return {"ok": True}
    if op == "clients":
        return {"ok": True, "clients": {str(port.address[1]): port.open_connections() for port in ports}}
    if op == "drop_sockets":
        count = sum(port.drop_all() for port in ports)
        with controller.lock:
            controller.event(f"dropped {count} client connections")
        return {"ok": True, "dropped": count}
    return {"ok": False, "error": f"unknown op {op!r}"}


def serve(controller: Controller, ports: Sequence[Listener], sock: socket.socket) -> None:
    for line in read_lines(sock):
        try:
            answer = handle(controller, json.loads(line), ports)
        except (ValueError, KeyError, TypeError) as exc:
            answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        sock.sendall((json.dumps(answer) + "\n").encode())


class ControlClient:
    """The test side of the control port."""

    def __init__(self, host: str, port: int = DEFAULT_PORT, timeout: float = 5.0) -> None:
        self._sock = socket.create_connection((host, port), timeout=timeout)
        self._file = self._sock.makefile("rwb")

    def __call__(self, op: str, **arguments) -> dict:
        self._file.write((json.dumps({"op": op, **arguments}) + "\n").encode())
        self._file.flush()
        answer = json.loads(self._file.readline())
        if not answer.get("ok"):
            raise RuntimeError(f"stand-in control port: {answer.get('error')}")
        return answer

    def close(self) -> None:
        self._file.close()
        self._sock.close()
