"""A session's files, sockets and pipes are all given back when it ends (issue 45, item 12, the
suite's part of it): participants opened, run and ended one after another leave the application's
process with the open file descriptors it had after the first. (The 15-minute `serve` soak with the
screens open, which also watches memory, is benchmarks/serve_soak.py.)"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest
from support.open_files import fds_after_sessions
from support.runner import READY_CEILING_S

#: Participants opened after the first, each with one handover.
AFTER_THE_FIRST = 3


@pytest.mark.slow
def test_ended_sessions_leave_no_open_file_behind(tmp_path: Path) -> None:
    """Each participant opens its database and lock file, a rig process with its pipe and shared
    memory, LSL outlets, a learner worker; after the first (which also starts what lives as long as
    the application: the learner's forkserver, the rig's helpers), ending a session must close what
    it opened. In a fresh process, as ``serve`` runs them: the test process's earlier tests leave
    threads and objects behind that are not the session's. (Four sessions with a learner each:
    40-90 s on two loaded cores.)"""
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        before, after, described = pool.submit(
            fds_after_sessions, tmp_path / "study", AFTER_THE_FIRST).result(
            timeout=(AFTER_THE_FIRST + 1) * 2 * READY_CEILING_S)  # a ceiling for a hung session
    opened = {fd: what for fd, what in after.items() if before.get(fd) != what}
    assert len(after) <= len(before), (f"{len(after) - len(before)} more open after "
                                       f"{AFTER_THE_FIRST} more sessions: {opened}\n{described}")
