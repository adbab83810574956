"""The rig process (robot_io.rig) with the mock arm and the simulated hand: a trial through real
messages and the shared-memory stream, and what happens when the rig dies or hangs."""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from multiprocessing.connection import _ConnectionBase
from pathlib import Path

import numpy as np
import pytest
from support.between import Between
from support.open_files import fd_targets, holders, open_fds
from support.waiting import CEILING_S, tail, wait_for

from robot_io.config import ControllerConfig
from robot_io.control.stages import Stage
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.client import RigClient
from robot_io.rig.messages import APP_SILENCE_S, RigDied, RigSpec, RunTrial, StageReached, TrialDone
from robot_io.rig.process import STACKS_SIGNAL
from robot_io.theta import Theta

pytestmark = [pytest.mark.slow, pytest.mark.soak]


class Reports:
    def __init__(self) -> None:
        self.queue: queue.Queue = queue.Queue()
        self.seen: list = []

    def __call__(self, _rig, report) -> None:
        self.queue.put(report)

    def until(self, predicate, what: str = "the expected report", timeout: float = 60.0):
        """The first report (from now on) that ``predicate`` accepts; ``timeout`` is a ceiling for a
        rig that never sends it, and the failure lists the reports that came instead."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                report = self.queue.get(timeout=0.1)
            except queue.Empty:
                continue
            self.seen.append(report)
            if predicate(report):
                return report
        raise AssertionError(f"gave up after {timeout:g} s waiting for {what}; the last reports: "
                             f"{[type(r).__name__ for r in self.seen[-10:]]}")


def trial(index: int = 1) -> RunTrial:
    return RunTrial(trial_index=index, theta=Theta(a=5.0, delta=-0.2, k=5.0), hand_seed=7,
                    automatic=True)


def rig(realtime: bool, reports: Reports) -> RigClient:
    """A rig on the mock arm and the simulated hand; on the wall clock it runs under SCHED_FIFO, as a
    lab runs it (``[loop] realtime_priority``): on the normal policy the suite's load can stall it
    past the backstop's 0.5 s."""
    return RigClient(RigSpec(config=ControllerConfig(), scenario=Scenario.STRAIGHTFORWARD,
                             realtime=realtime, realtime_priority=realtime), reports)


def test_a_trial_through_the_rig_process_streams_its_samples_through_shared_memory():
    reports = Reports()
    client = rig(realtime=False, reports=reports)
    try:
        assert client.devices.arm == "mock" and client.pid != os.getpid()
        client.run_trial(trial())
        done = reports.until(lambda r: isinstance(r, TrialDone))
        samples = client.stream.columns()
    finally:
        client.close()
    assert done.summary.outcome == "completed" and done.rows == done.summary.cycles
    assert len(samples["t"]) == done.rows
    np.testing.assert_allclose(np.diff(samples["t"]), 1 / 500)
    assert samples["stage"][-1] == 3 and np.nanmax(samples["pull"]) == pytest.approx(
        done.summary.peak_pull_n)


@contextlib.contextmanager
def stderr_to(path: Path) -> Iterator[None]:
    """This process's fd 2 appends to ``path`` while inside, so a child started meanwhile writes
    its stderr there for good; read it with a fresh open. (capfd's ``readouterr()`` seeks back and
    truncates a file whose offset the child shares: what the child writes in between is lost, as a
    run of two suites side by side lost the middle of a stack dump.)"""
    saved = os.dup(2)
    try:
        with path.open("ab") as out:
            os.dup2(out.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def test_a_rig_asked_for_its_stacks_prints_them_and_runs_on(tmp_path):
    """What the backstop sends a hung rig before killing it: each thread's stack on stderr (the
    application's log), to find the hang afterwards. The default action would end the rig."""
    reports, log = Reports(), tmp_path / "rig-stderr.log"
    with stderr_to(log):
        client = rig(realtime=False, reports=reports)
    try:
        os.kill(client.pid, STACKS_SIGNAL)
        # the dump comes a thread at a time (the inbox's frames are in process.py too): wait for
        # the main thread's, which is printed last
        wait_for(lambda: "in spawn_main" in log.read_text(), "the rig's stacks on stderr",
                 seen=lambda: tail(log.read_text()))
        err = log.read_text()
        assert 'File "' in err and "robot_io/rig/process.py" in err and "in main" in err
        assert client.alive
        client.run_trial(trial())
        assert reports.until(lambda r: isinstance(r, TrialDone)).summary.outcome == "completed"
    finally:
        client.close()


@contextlib.contextmanager
def rig_at(stage: Stage) -> Iterator[tuple[RigClient, Reports]]:
    """A real-time rig whose first trial has reached ``stage``; closed on the way out."""
    reports = Reports()
    client = rig(realtime=True, reports=reports)
    try:
        client.run_trial(trial())
        reports.until(lambda r: isinstance(r, StageReached) and r.stage == stage)
        yield client, reports
    finally:
        client.close()


def test_a_rig_killed_mid_reach_is_reported_with_the_stage_and_its_samples_so_far_remain():
    with rig_at(Stage.REACH) as (client, reports):
        # some of the reach written (counted rows, not a sleep): what must survive the kill
        wait_for(lambda: len(client.stream.columns()["t"]) > 10, "11 rows of the reach in the stream",
                 seen=lambda: len(client.stream.columns()["t"]))
        os.kill(client.pid, signal.SIGKILL)
        died = reports.until(lambda r: isinstance(r, RigDied))
        samples = client.stream.columns()
    assert died.trial_index == 1
    assert "killed by signal 9" in died.reason and "during reach" in died.reason
    t = samples["t"]  # what the rig wrote before it died: the reach from Go on, cycle by cycle
    assert len(t) > 10 and 0 <= t[0] < 0.01 and np.all(np.diff(t) > 0)
    assert np.all(samples["stage"][1:-1] == 1)  # the last row was being written when it died


def freeze(pid: int) -> None:
    """SIGSTOP the process and wait until the kernel shows it stopped (every thread frozen)."""
    os.kill(pid, signal.SIGSTOP)
    state = lambda: Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0]  # noqa: E731
    wait_for(lambda: state() == "T", f"process {pid} stopped (T in /proc)", seen=state, poll=0.001)


def test_a_rig_that_hangs_mid_reach_is_stopped_by_the_backstop_without_being_asked():
    with rig_at(Stage.REACH) as (client, reports):
        freeze(client.pid)  # the loop freezes: no sample, no answer
        died = reports.until(lambda r: isinstance(r, RigDied), "the backstop's RigDied")
    assert "killed by signal 9" in died.reason


def test_stop_reaches_a_hung_rig_through_the_backstop():
    with rig_at(Stage.GO) as (client, _):
        freeze(client.pid)
        acknowledged = client.stop("stopped by the experimenter (Stop)")
        alive = client.alive
    assert not acknowledged and not alive


def reap(client: RigClient) -> None:
    """Ask for the rig's exit code until it is known (as the report reader does once the pipe ends)."""
    while client.exit_code is None:
        time.sleep(0.001)


def test_a_rig_that_exits_while_other_threads_reap_it_closes_cleanly(caplog):
    """Issue 25, item 13: the report reader reaps the rig the moment it exits after Shutdown; a
    close() whose own ``waitpid`` then finds no child used to take that for a rig still running,
    log "did not exit within 5 s" at once and fire the backstop on a rig that had exited cleanly.
    Here three more threads reap beside the reader, so close() loses that race most times."""
    for attempt in range(5):
        client = rig(realtime=False, reports=Reports())
        reaping = [threading.Thread(target=reap, args=(client,)) for _ in range(3)]
        for thread in reaping:
            thread.start()
        with caplog.at_level(logging.ERROR, logger="robot_io.rig.client"):
            client.close()
        for thread in reaping:
            thread.join(CEILING_S)
        assert client.exit_code == 0, f"close {attempt}: exit code {client.exit_code}"
        assert not caplog.records, f"close {attempt}: {[r.getMessage() for r in caplog.records]}"


def pipes_between(pid: int) -> set[str]:
    """The pipes (``pipe:[inode]``) that this process and process ``pid`` hold, and no other (not
    the resource tracker's, which every spawned child inherits)."""
    ours = {what for what in open_fds().values() if what.startswith("pipe:[")}
    return {what for what in ours & set(fd_targets(str(pid))) if len(holders(what)) == 2}


@pytest.mark.parametrize("end", ["closed", "killed, then closed"])
def test_a_closed_rig_gives_back_its_process_handle(end):
    """A session's end gives back the rig's process handle with its pipes (the sentinel that the
    rig holds the other end of) as soon as the rig is reaped and the reader is done, not when the
    garbage collector or some later start gets to it. ``multiprocessing`` kept a child whose exit
    code was read, but that no join had seen end, in a list of its own: test_open_files.py
    (tests/session) failed now and then with two pipes more, the last session's rig's. A dead rig
    is reaped by the report reader before close() looks."""
    reports = Reports()
    client = rig(realtime=False, reports=reports)
    pid = client.pid
    assert pid is not None
    handle = pipes_between(pid)
    assert handle, f"no pipe shared with the rig {pid}: {open_fds()}"
    if end != "closed":
        os.kill(pid, signal.SIGKILL)
        reports.until(lambda r: isinstance(r, RigDied), "the reader's RigDied")
    client.close()
    assert client.reports_handed_on(CEILING_S), "the reader did not end"
    still = handle & set(open_fds().values())
    assert not still, f"the rig's handle kept {still} open after close() and the reader's end"
    assert client.pid is None  # a reused number is never taken for the rig
    assert client.exit_code == (0 if end == "closed" else -signal.SIGKILL)


def test_close_never_closes_the_report_pipe_under_the_reader(monkeypatch):
    """The report reader may be anywhere in ``recv`` when close() is called (a loaded machine
    leaves it between two reports). Here it is held between recv's check that the pipe is open and
    its read while close() shuts the rig down: if close() closed the pipe there, the read would take
    a handle gone None (a TypeError that kills the thread, seen once beside a second suite) or, had
    the number been reused, read another file. The pipe must end with the reader, and only then."""
    died: list[threading.ExceptHookArgs] = []
    monkeypatch.setattr(threading, "excepthook", died.append)
    between = Between(_ConnectionBase.recv, "self._recv_bytes()")
    reports = Reports()
    with between.tracing():
        client = rig(realtime=False, reports=reports)
    try:
        between.arm()  # the reader's next recv, after the report below
        assert client.stop("a report for the reader to go round with")
        wait_for(between.holding.is_set, "the reader held inside recv, past its check",
                 seen=lambda: f"reports {reports.seen}, reader alive {client._reader.is_alive()}")
        client.close()  # the rig exits; the reader is still held
        assert client.exit_code == 0
    finally:
        between.release()
    client._reader.join(CEILING_S)
    assert not client._reader.is_alive(), "the reader did not end with the rig's pipe"
    assert not died, f"the reader died: {died[0].exc_type.__name__}: {died[0].exc_value}"
    assert client._conn.closed, "the reader left the pipe open"


def hold_the_interpreter(seconds: float, at: float | None = None,
                         then: Callable[[], None] | None = None) -> None:
    """Hang this process (the rig's application) as a stuck computation does: one thread keeps the
    interpreter's lock for ``seconds``, so no other thread of it (the heartbeat's) runs; ``then()``
    is called ``at`` seconds into the hold, still holding it."""
    interval = sys.getswitchinterval()
    sys.setswitchinterval(seconds * 10)  # no other thread is handed the lock before the loop ends
    try:
        start = time.monotonic()
        while (now := time.monotonic()) < start + seconds:
            if then is not None and at is not None and now >= start + at:
                then()
                then = None
    finally:
        sys.setswitchinterval(interval)


def waiting_for_go(reports: Reports) -> RigClient:
    """A rig on the wall clock whose trial has been loaded and waits for Go (no end of its own)."""
    client = rig(realtime=True, reports=reports)
    client.run_trial(trial().model_copy(update={"automatic": False}))
    reports.until(lambda r: isinstance(r, StageReached) and r.stage == Stage.PREPARE)
    client.confirm(Stage.PREPARE)  # Object loaded
    reports.until(lambda r: isinstance(r, StageReached) and r.stage == Stage.READY)
    return client


def test_a_rig_whose_application_hangs_mid_trial_stops_the_arm_and_says_why():
    """Issue 25, item 1, the other half of the frozen application (a stopped one is in
    tests/session/test_frozen_application.py): one that still runs but sends nothing, here holding
    its interpreter's lock, has its trial stopped by the rig after APP_SILENCE_S."""
    reports = Reports()
    client = waiting_for_go(reports)
    try:
        hold_the_interpreter(APP_SILENCE_S + 1.0)
        done = reports.until(lambda r: isinstance(r, TrialDone), "the stopped trial's TrialDone")
    finally:
        client.close()
    assert done.summary.outcome == "stopped" and done.rows == 0, done.summary
    assert done.summary.reason.startswith("the application sent nothing for"), done.summary.reason


def test_a_machine_held_still_is_not_taken_for_a_hung_application():
    """What CI met: the whole machine held still for 4 s (a stand-in under SCHED_FIFO sent a
    sample 4 s late) and the rig, run again, stopped the trial for its application's 4 s of silence
    before the application had run again to send anything. Here the rig is frozen (SIGSTOP) while
    its application sends nothing for APP_SILENCE_S + 1 s; it runs again while the application still
    holds its interpreter's lock (0.3 s more). The silence the rig itself slept through is not the
    application's: the trial still waits for Go, and completes after it."""
    reports = Reports()
    client = waiting_for_go(reports)
    try:
        freeze(client.pid)
        hold_the_interpreter(APP_SILENCE_S + 1.3, at=APP_SILENCE_S + 1.0,
                             then=lambda: os.kill(client.pid, signal.SIGCONT))
        client.confirm(Stage.READY)  # Go
        done = reports.until(lambda r: isinstance(r, TrialDone), "the trial's TrialDone")
    finally:
        client.close()
    assert done.summary.outcome == "completed", done.summary
