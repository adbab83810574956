"""What a process has open, and one fresh process running sessions one after another, for
tests/session/test_open_files.py.

The sessions run in a process of their own (spawned: nothing of the test process's earlier tests,
their threads or their garbage, is in it), as ``serve`` runs them; it reports its open file
descriptors after the first session and after the others, and describes what is new.
"""

from __future__ import annotations

import contextlib
import gc
import os
import re
import subprocess
from multiprocessing.process import BaseProcess
from pathlib import Path

from app.session.config import LabConfig
from app.session.runner import SessionRunner
from robot_io.hands.simulated_hand import Scenario
from support.engine import SHORT_PROTOCOL
from support.runner import READY_CEILING_S, Probe

LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": SHORT_PROTOCOL})


def open_fds() -> dict[int, str]:
    """This process's open file descriptors and what each is (a file's path, socket:[…], pipe:[…])."""
    found = {}
    for name in os.listdir("/proc/self/fd"):
        with contextlib.suppress(FileNotFoundError):  # the one listdir itself had open
            found[int(name)] = os.readlink(f"/proc/self/fd/{name}")
    return found


def fd_targets(pid: str) -> list[str]:
    """What process ``pid``'s open file descriptors are (none if it has gone or is not ours)."""
    targets = []
    with contextlib.suppress(OSError):
        for fd in os.listdir(f"/proc/{pid}/fd"):
            with contextlib.suppress(OSError):  # closed while listed (the listing's own, for one)
                targets.append(os.readlink(f"/proc/{pid}/fd/{fd}"))
    return targets


def holders(what: str) -> list[str]:
    """The processes (pid and name; "this one" for the caller) with ``what`` (``socket:[inode]``,
    ``pipe:[inode]``) open."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        if what in fd_targets(pid):
            with contextlib.suppress(OSError):
                name = Path(f"/proc/{pid}/comm").read_text().strip()
                found.append("this one" if int(pid) == os.getpid() else f"{pid} {name}")
    return found


def process_handles() -> dict[int, str]:
    """The sentinels of this process's ``multiprocessing`` handles of started children that are
    not closed (fd: name and pid): a handle keeps its sentinel and one more pipe open."""
    found = {}
    for handle in gc.get_objects():
        if isinstance(handle, BaseProcess):
            with contextlib.suppress(ValueError):  # not started, or closed
                found[handle.sentinel] = f"{handle.name} (pid {handle.pid})"
    return found


def what_they_are(described: dict[int, str]) -> str:
    """For a failure message: each socket among ``described`` with its kind, its addresses and, for
    a Unix socket, who holds its peer (``ss``: a pair of ours is a multiprocessing Pipe, a peer in a
    child says which child); each pipe with the processes that hold it (its other end) and, if it
    is one, the child process handle whose sentinel it is."""
    table = subprocess.run(["ss", "-axtuwn", "-e"], capture_output=True, text=True).stdout
    rows = {}
    for line in table.splitlines():
        fields = line.split()
        if line.startswith("u_") and len(fields) > 7:
            rows[fields[5]] = (" ".join(fields[:8]), fields[7])
        elif match := re.search(r"ino:(\d+)", line):
            rows[match.group(1)] = (" ".join(fields[:6]), None)
    lines, sentinels = [], process_handles() if described else {}
    for fd, what in sorted(described.items()):
        if what.startswith("socket:["):
            row, peer = rows.get(what[len("socket:["):-1], ("not in ss", None))
            lines.append(f"fd {fd} {what}: {row}" + (
                f"; peer held by {holders(f'socket:[{peer}]')}" if peer and peer != "0" else ""))
        elif what.startswith("pipe:["):
            lines.append(f"fd {fd} {what}: held by {holders(what)}" + (
                f"; the sentinel of the process handle {sentinels[fd]}" if fd in sentinels else ""))
    return "\n".join(lines)


def one_session(runner: SessionRunner, probe: Probe, code: str) -> None:
    """Open ``code``, let the simulated participant and experimenter run one handover, end it."""
    runner.open(code, Scenario.STRAIGHTFORWARD)
    runner.set_auto(True)
    probe.wait(lambda v: v.state is not None and v.state.completed >= 1,
               what=f"{code}'s first handover", timeout=READY_CEILING_S)
    probe.wait(lambda v: v.step is not None and v.step.value != "running",
               what=f"{code}'s trial to end")
    runner.end_session()


def fds_after_sessions(study: Path, after_the_first: int) -> tuple[dict[int, str], dict[int, str], str]:
    """In this process: a runner of ``study``, one session, then ``after_the_first`` more; the open
    file descriptors after the first and after the last, and what the new ones are."""
    runner = SessionRunner(study, LAB, auto_experimenter=True)
    probe = Probe(runner)
    try:
        one_session(runner, probe, "F00")
        before = open_fds()
        for n in range(1, after_the_first + 1):
            one_session(runner, probe, f"F{n:02d}")
        after = open_fds()
    finally:
        runner.close()
    return before, after, what_they_are({fd: what for fd, what in after.items()
                                         if before.get(fd) != what})
