"""With ``HANDOVER_TEST_CPU=1``: the CPU time each test used, its most CPU-hungry tests listed at
the end of the run.

On a 2-core machine the suite's wall time follows its CPU time, which ``--durations`` does not show:
a test that waits a minute for a session costs little, one whose Chromium draws for a minute costs a
core. A test's CPU is the user + system time that the process running it and every process in its
tree (a server, a run-session, a learner, Chromium and its renderers) used from the test's setup to
its teardown. A thread samples the tree every :data:`PERIOD_S`, so a process that starts and ends
between two samples, or the last period of one that ends, is not seen. Off by default: the thread
holds the GIL while it reads /proc, and a test's real-time threads in the same process wait for it
while the machine's load keeps the (normal-priority) sampler off the CPU: in the one full run with
it on, the in-process LSL handover of test_hand_sources went 0.24 s without a hand sample (a
failure not seen in the runs without it).
"""

from __future__ import annotations

import os
import threading
import time

import psutil
import pytest

#: Every how many seconds the process tree is read.
PERIOD_S = 1.0
#: How many tests the summary lists.
LISTED = 25
#: The key of a test's CPU seconds in its teardown report's ``user_properties`` (xdist carries
#: them from a worker to the controller).
KEY = "cpu_s"
ENABLED = os.environ.get("HANDOVER_TEST_CPU") == "1"


class TreeCpu:
    """The user + system seconds of every process seen in this process's tree, by (pid, start)."""

    def __init__(self) -> None:
        self.seen: dict[tuple[int, float], float] = {}
        self.lock = threading.Lock()
        self.thread: threading.Thread | None = None

    def sample(self) -> dict[tuple[int, float], float]:
        me = psutil.Process()
        for process in (me, *me.children(recursive=True)):
            try:
                with process.oneshot():
                    key, times = (process.pid, process.create_time()), process.cpu_times()
            except psutil.Error:  # ended between the listing and the reading
                continue
            with self.lock:
                self.seen[key] = times.user + times.system
        with self.lock:
            return dict(self.seen)

    def start(self) -> None:
        if self.thread is None:
            self.thread = threading.Thread(target=self._run, name="test-cpu", daemon=True)
            self.thread.start()

    def _run(self) -> None:
        while True:
            self.sample()
            time.sleep(PERIOD_S)  # a sampling period, not a wait for a state


_tree = TreeCpu()
_started: dict[str, dict[tuple[int, float], float]] = {}
_measured: list[tuple[float, str]] = []


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    if ENABLED:
        _tree.start()
        _started[item.nodeid] = _tree.sample()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    if call.when == "teardown" and item.nodeid in _started:
        before, after = _started.pop(item.nodeid), _tree.sample()
        used = sum(seconds - before.get(key, 0.0) for key, seconds in after.items())
        outcome.get_result().user_properties.append((KEY, used))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _measured.extend((value, report.nodeid) for key, value in report.user_properties if key == KEY)


def pytest_terminal_summary(terminalreporter) -> None:
    if not _measured:
        return
    total = sum(seconds for seconds, _ in _measured)
    terminalreporter.write_sep("=", f"most CPU: {min(LISTED, len(_measured))} of {len(_measured)} tests, "
                                    f"{total:.0f} CPU-s in all (with the processes each started)")
    for seconds, nodeid in sorted(_measured, reverse=True)[:LISTED]:
        terminalreporter.write_line(f"{seconds:8.2f}s  {nodeid}")
