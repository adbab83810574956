"""With ``HANDOVER_TEST_CPU=1``: the CPU time each test used, its most CPU-hungry tests listed at
the end of the run, and the run's CPU by the kind of process that used it (:func:`kind`).

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
#: The key of a test's CPU seconds by process kind in its teardown report's ``user_properties``
#: (xdist carries them from a worker to the controller); the test's CPU is their sum.
KEY = "cpu_s_by_kind"
ENABLED = os.environ.get("HANDOVER_TEST_CPU") == "1"


def kind(command: list[str], test_process: bool) -> str:
    """What a process of a test's tree is, from its command line: the run's CPU is summed by these
    kinds, which say where a change of design would save time (a page, a learner, a rig, a server)."""
    line = " ".join(command)
    if test_process:
        return "the test process"
    if "chromium" in line:
        role = line.split("--type=", 1)[1].split()[0] if "--type=" in line else "browser"
        return f"Chromium {role}" if role in ("renderer", "gpu-process") else "Chromium, other"
    if "playwright" in line:
        return "Playwright driver"
    if "multiprocessing.forkserver" in line:
        return "learner forkserver and its learners"
    if "multiprocessing" in line:
        return "spawned processes (rigs, Dask workers, resource trackers)"
    if "app.cli" in command or any(word.endswith("/handover") for word in command[:2]):
        word = next((word for word in ("serve", "run-session") if word in command), None)
        return f"handover {word}" if word else "other handover commands"
    return "other (forks of the test process, tools)"


class TreeCpu:
    """The user + system seconds of every process seen in this process's tree, by (pid, start),
    and each one's :func:`kind`."""

    def __init__(self) -> None:
        self.seen: dict[tuple[int, float], float] = {}
        self.kinds: dict[tuple[int, float], str] = {}
        self.lock = threading.Lock()
        self.thread: threading.Thread | None = None

    def sample(self) -> dict[tuple[int, float], float]:
        me = psutil.Process()
        for process in (me, *me.children(recursive=True)):
            try:
                with process.oneshot():
                    key, times = (process.pid, process.create_time()), process.cpu_times()
                    if key not in self.kinds:
                        self.kinds[key] = kind(process.cmdline(), process.pid == me.pid)
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
_by_kind: dict[str, float] = {}


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
        used: dict[str, float] = {}
        for key, seconds in after.items():
            name = _tree.kinds[key]
            used[name] = used.get(name, 0.0) + seconds - before.get(key, 0.0)
        outcome.get_result().user_properties.append((KEY, used))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    for used in (value for key, value in report.user_properties if key == KEY):
        _measured.append((sum(used.values()), report.nodeid))
        for name, seconds in used.items():
            _by_kind[name] = _by_kind.get(name, 0.0) + seconds


def pytest_terminal_summary(terminalreporter) -> None:
    if not _measured:
        return
    total = sum(seconds for seconds, _ in _measured)
    terminalreporter.write_sep("=", f"most CPU: {min(LISTED, len(_measured))} of {len(_measured)} tests, "
                                    f"{total:.0f} CPU-s in all (with the processes each started)")
    for seconds, nodeid in sorted(_measured, reverse=True)[:LISTED]:
        terminalreporter.write_line(f"{seconds:8.2f}s  {nodeid}")
    terminalreporter.write_sep("=", "CPU by kind of process (every test's, summed)")
    for name, seconds in sorted(_by_kind.items(), key=lambda item: -item[1]):
        terminalreporter.write_line(f"{seconds:8.2f}s  {name}")
