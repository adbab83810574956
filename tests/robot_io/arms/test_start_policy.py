"""No Python interpreter starts under SCHED_FIFO. A child inherits its parent thread's policy, and
an interpreter starting (under spawn it runs the parent's main module again, then imports what it
needs) is a fraction of a second to seconds of CPU with nothing to block on. The rig runs under
SCHED_FIFO, so ur_rtde's control worker, which it starts, started under it: in `make soak` the
rehearsal's tracker (FIFO at the same priority) was then held off the CPU and sent a sample 104 ms
late, and the trial after a fresh rig ended tracker_lost, "no valid hand sample for 0.104 s"."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from support.priority import realtime_threads
from support.ur import standin
from support.waiting import wait_for

from robot_io.arms.ur_worker import COMMAND_PRIORITY_BELOW, ControlWorker
from robot_io.clock import SUPPORT_PRIORITY, children_start_on_the_normal_policy

pytestmark = [pytest.mark.soak, pytest.mark.standin]

needs_fifo = pytest.mark.skipif(not hasattr(os, "SCHED_FIFO") or os.geteuid() != 0,
                                reason="SCHED_FIFO needs root or CAP_SYS_NICE")

FIRST_LINE = "import os; print(os.sched_getscheduler(0), flush=True)"


@needs_fifo
def test_a_child_started_from_a_fifo_thread_starts_on_the_normal_policy():
    with realtime_threads():
        inherited = subprocess.run([sys.executable, "-c", FIRST_LINE], capture_output=True, text=True)
        with children_start_on_the_normal_policy() as priority:
            started = subprocess.run([sys.executable, "-c", FIRST_LINE], capture_output=True, text=True)
        after = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    assert int(inherited.stdout) == os.SCHED_FIFO  # the inheritance this guards against
    assert int(started.stdout) == os.SCHED_OTHER
    assert priority == SUPPORT_PRIORITY
    assert after == (os.SCHED_FIFO, SUPPORT_PRIORITY)  # the thread itself keeps its policy


def test_a_child_started_from_a_normal_thread_is_given_no_priority():
    with children_start_on_the_normal_policy() as priority:
        started = subprocess.run([sys.executable, "-c", FIRST_LINE], capture_output=True, text=True)
    assert priority is None and int(started.stdout) == os.sched_getscheduler(0)


class Births:
    """Watches this process's threads for new children (``/proc/<pid>/task/*/children``) and records
    each one's policy when first seen, from a thread above the SCHED_FIFO ones it watches."""

    def __init__(self) -> None:
        self.before = self.children()
        self.policies: dict[int, int] = {}
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)

    @staticmethod
    def children() -> set[int]:
        found: set[int] = set()
        for task in Path(f"/proc/{os.getpid()}/task").iterdir():
            with contextlib.suppress(OSError):  # the thread ended meanwhile
                found.update(int(pid) for pid in (task / "children").read_text().split())
        return found

    def _watch(self) -> None:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(SUPPORT_PRIORITY + 5))
        while not self._done.is_set():
            for pid in self.children() - self.before - self.policies.keys():
                with contextlib.suppress(OSError):  # it exited meanwhile
                    self.policies[pid] = os.sched_getscheduler(pid)
            self._done.wait(0.0005)

    def __enter__(self) -> Births:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join()


@needs_fifo
def test_the_ur_rtde_control_worker_starts_on_the_normal_policy_then_runs_under_fifo():
    with standin() as ur, realtime_threads(), Births() as births:
        worker = ControlWorker(ur.host, upper_range_registers=False, timeout=60.0)
        try:
            pid = worker.process.pid
            wait_for(lambda: pid in births.policies, "the worker's birth seen",
                     seen=lambda: births.policies)
            running = {tid: (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority)
                       for tid in map(int, os.listdir(f"/proc/{pid}/task"))}
        finally:
            worker.close()
    assert births.policies[pid] == os.SCHED_OTHER, "the worker started under SCHED_FIFO"
    # raised itself once its imports were done: ur_rtde's threads at the rig's priority, the thread
    # that sends commands (and spins in ur_rtde's waits for "ready") below them
    assert running.pop(pid) == (os.SCHED_FIFO, SUPPORT_PRIORITY - COMMAND_PRIORITY_BELOW)
    assert running and set(running.values()) == {(os.SCHED_FIFO, SUPPORT_PRIORITY)}, running
