"""A session's files, sockets and pipes are all given back when it ends (issue 45, item 12, the
suite's part of it): participants opened, run and ended one after another leave the application's
process with the open file descriptors it had after the first. (The 15-minute `serve` soak with the
screens open, which also watches memory, is benchmarks/serve_soak.py.)"""

from __future__ import annotations

import contextlib
import gc
import os
from pathlib import Path

import pytest
from support.engine import SHORT_PROTOCOL
from support.runner import READY_CEILING_S, Probe

from app.session.config import LabConfig
from app.session.runner import SessionRunner
from robot_io.hands.simulated_hand import Scenario

LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": SHORT_PROTOCOL})
#: Participants opened after the first, each with one handover.
AFTER_THE_FIRST = 3


def open_fds() -> dict[int, str]:
    """This process's open file descriptors and what each is (a file's path, socket:[…], pipe:[…])."""
    found = {}
    for name in os.listdir("/proc/self/fd"):
        with contextlib.suppress(FileNotFoundError):  # the one listdir itself had open
            found[int(name)] = os.readlink(f"/proc/self/fd/{name}")
    return found


def one_session(runner: SessionRunner, probe: Probe, code: str) -> None:
    """Open ``code``, let the simulated participant and experimenter run one handover, end it."""
    runner.open(code, Scenario.STRAIGHTFORWARD)
    runner.set_auto(True)
    probe.wait(lambda v: v.state is not None and v.state.completed >= 1,
               what=f"{code}'s first handover", timeout=READY_CEILING_S)
    probe.wait(lambda v: v.step is not None and v.step.value != "running",
               what=f"{code}'s trial to end")
    runner.end_session()


@pytest.mark.slow
def test_ended_sessions_leave_no_open_file_behind(tmp_path: Path) -> None:
    """Each participant opens its database and lock file, a rig process with its pipe and shared
    memory, LSL outlets, a learner worker; after the first (which also starts what lives as long as
    the application: the learner's forkserver, the rig's helpers), ending a session must close what
    it opened, by its own close, not by the garbage collector later. (Four sessions with a learner each: 40-90 s on two loaded cores.)"""
    runner = SessionRunner(tmp_path / "study", LAB, auto_experimenter=True)
    probe = Probe(runner)
    gc.disable()  # what only the garbage collector would release is not released by the close
    try:
        one_session(runner, probe, "F00")
        before = open_fds()
        for n in range(1, AFTER_THE_FIRST + 1):
            one_session(runner, probe, f"F{n:02d}")
        after = open_fds()
    finally:
        gc.enable()
        runner.close()
    opened = {fd: what for fd, what in after.items() if before.get(fd) != what}
    assert len(after) <= len(before), (f"{len(after) - len(before)} more open after "
                                       f"{AFTER_THE_FIRST} more sessions: {opened}")
