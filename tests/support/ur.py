"""A stand-in UR controller per test, in its own process on a loopback address of its own.

The stand-in listens on a UR's fixed ports (RTDE 30004, dashboard 29999, ...), so two tests, xdist
workers or suites running at once each need their own address: :func:`standin` takes a free
127.0.x.y (bind-checked, as a rehearsal does) and tries another if the stand-in finds it taken
after all (another process bound it between the check and the stand-in's bind).
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass

from app.session.rehearsal import free_loopback_host
from robot_io.standins.ur.control import ControlClient
from support.waiting import tail, wait_for

#: Command ids of ur_rtde's control script (rtde.h, RobotCommand::Type).
MOVEL, SERVO_STOP, SERVOL, SET_WATCHDOG, STOP_SCRIPT = 3, 16, 24, 35, 255
#: How many free addresses to try when the chosen one is taken before the stand-in binds it.
ATTEMPTS = 5


@dataclass
class Standin:
    """A running stand-in: its address, its control port's client and its process."""

    host: str
    control: ControlClient
    process: subprocess.Popen


@contextlib.contextmanager
def standin(series: str = "cb3") -> Iterator[Standin]:
    """Start ``python -m robot_io.standins.ur`` on a free loopback address; yield it; always end it.

    The child exits when its stdin closes, so it cannot outlive a test process that dies. It runs
    under SCHED_FIFO where the OS allows it, as a rehearsal's does: a UR controller has hardware of
    its own, and a stand-in starved for 0.1 s by the suite's load is an arm fault ("no new state")."""
    for _ in range(ATTEMPTS):
        host = free_loopback_host()
        with tempfile.TemporaryFile("w+") as stderr:
            process = subprocess.Popen(
                [sys.executable, "-m", "robot_io.standins.ur", "--host", host, "--series", series,
                 "--exit-with-stdin", "--realtime-priority"],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=stderr, text=True)
            try:
                line = process.stdout.readline()  # "ready <host>", or EOF if it could not start
                if line.strip() == f"ready {host}":
                    control = ControlClient(host)
                    try:
                        yield Standin(host, control, process)
                    finally:
                        control.close()
                    return
                process.wait(30)
                stderr.seek(0)
                log = stderr.read()
                if "Address already in use" not in log:
                    raise AssertionError(f"the stand-in on {host} did not start ({line!r}); "
                                         f"exit code {process.returncode}; stderr: {tail(log)}")
            finally:
                _end(process)
                _show_log(stderr, host)
    raise AssertionError(f"no free loopback address for a stand-in after {ATTEMPTS} tries")


def _show_log(stderr, host: str) -> None:
    """What the stand-in logged, on the test's stderr: pytest shows it beside a failure (a
    warning of the stand-in's, such as a package for an unknown recipe, explains what the test saw)."""
    stderr.seek(0)
    if log := stderr.read().strip():
        print(f"the stand-in on {host} logged:\n{tail(log)}", file=sys.stderr)


def _end(process: subprocess.Popen) -> None:
    """Close its stdin (it exits) and wait for its exit; killed if it does not end."""
    if process.stdin is not None and not process.stdin.closed:
        process.stdin.close()
    try:
        process.wait(30)  # a ceiling: it exits within a cycle of its stdin closing
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(30)
    if process.stdout is not None:
        process.stdout.close()


def servo_targets(control: ControlClient) -> list[tuple[float, list[float]]]:
    """(time, xyz) of every servoL the stand-in received, in order."""
    return [(t, values[:3]) for t, command, values in control("received")["received"]
            if command == SERVOL]


def commands(control: ControlClient) -> list[int]:
    return [command for _, command, _ in control("received")["received"]]


def servo_targets_once_stopped(control: ControlClient) -> list[tuple[float, list[float]]]:
    """:func:`servo_targets` once the stand-in's control script has stopped.

    Call it after ending the stream (``URArm.stop()`` or ``close()``, or a fault): the script ends on
    stopScript, on a safety stop or on its watchdog (no target for 1/watchdog_hz s), and the
    stand-in records commands only while it runs, so once it has stopped no target can still be
    on the way to the record."""
    wait_for(lambda: not control("state")["program"], "the stand-in's control script to stop",
             seen=lambda: f"program {control('state')['program']!r}, last commands received "
                          f"{commands(control)[-10:]}")
    return servo_targets(control)


def settled_servo_targets(control: ControlClient, arm, expected: int) -> list[tuple[float, list[float]]]:
    """:func:`servo_targets` once ``expected`` have arrived and ``arm``'s stream has ended (the
    stand-in reads its command registers once per cycle: the targets are waited for before the stop
    overwrites them); any stray sent after them is in the record by then."""
    if expected:
        wait_for(lambda: len(servo_targets(control)) >= expected, f"{expected} servo targets",
                 seen=lambda: f"{len(servo_targets(control))}; commands {commands(control)[-10:]}")
    arm.stop()
    return servo_targets_once_stopped(control)
