"""A stand-in UR controller per test, in its own process on its own loopback address."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import time
from collections.abc import Iterator

from robot_io.ur_standin.control import ControlClient

#: Command ids of ur_rtde's control script (rtde.h, RobotCommand::Type).
MOVEL, SERVO_STOP, SERVOL, SET_WATCHDOG, STOP_SCRIPT = 3, 16, 24, 35, 255


@contextlib.contextmanager
def standin(host: str, series: str = "cb3") -> Iterator[ControlClient]:
    """Start ``python -m robot_io.ur_standin`` on ``host``; yield its control client; always end it.

    The child exits when its stdin closes, so it cannot outlive a test process that dies."""
    process = subprocess.Popen(
        [sys.executable, "-m", "robot_io.ur_standin", "--host", host, "--series", series,
         "--exit-with-stdin"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    client = None
    try:
        line = process.stdout.readline()
        assert line.strip() == f"ready {host}", f"stand-in did not start: {line!r}"
        client = ControlClient(host)
        yield client
    finally:
        if client is not None:
            client.close()
        process.stdin.close()
        try:
            process.wait(5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5)


def servo_targets(control: ControlClient) -> list[tuple[float, list[float]]]:
    """(time, xyz) of every servoL the stand-in received, in order."""
    return [(t, values[:3]) for t, command, values in control("received")["received"]
            if command == SERVOL]


def settled_servo_targets(control: ControlClient, expected: int, timeout: float = 2.0):
    """:func:`servo_targets` once ``expected`` have arrived (or ``timeout``), plus 0.1 s for strays."""
    deadline = time.monotonic() + timeout
    while len(servo_targets(control)) < expected and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.1)
    return servo_targets(control)


def commands(control: ControlClient) -> list[int]:
    return [command for _, command, _ in control("received")["received"]]
