"""A run of the suite that stops making progress ends, with every process's stack, naming the tests.

Three ways a run stopped making progress, and what ends each (issue 44):

- **A test kills its xdist worker** (``os.abort()``, a segmentation fault): xdist replaced the worker
  and, under ``--dist loadgroup``, put the crashed test's group back in a queue that no worker took:
  the run waited for good. Here ``--max-worker-restart`` is 0 unless given: the first crash ends
  the run; xdist reports the test ("worker 'gw1' crashed while running '…'").
- **A hung test**: pytest-timeout's ceiling (pyproject's ``timeout``) ends its worker: a crash, as
  above. In an xdist worker the stacks that pytest-timeout prints went nowhere (a worker's terminal
  is not the run's), so there the timer is faulthandler's: at the ceiling it prints every thread's
  stack to the run's stderr and ends the worker, from C, so a test that holds the GIL ends too.
- **A hung scheduler, or a worker hung outside any test** (collection, a session's teardown): this
  watchdog, in the xdist controller. When no test is running and nothing has happened for
  ``watchdog_idle`` seconds (or, while tests run, nothing for the longest ceiling among them plus
  that: pytest-timeout's, the test's own ``timeout`` mark or the run's; none with ``--timeout=0``), it
  prints the tests in flight, the controller's threads (faulthandler) and every process of the run
  (psutil: pid, state, CPU, command) with its Python stack (``py-spy dump``), kills the workers and
  everything they started, and makes the run's exit status non-zero.

At the end of every xdist run it also names the collected tests that never reported (a scheduler
that drops tests), and fails a run that would otherwise pass without them.
"""

from __future__ import annotations

import _thread
import contextlib
import faulthandler
import os
import shutil
import subprocess
import sys
import threading
import time
from typing import TextIO

import psutil
import pytest

#: Default of the ``watchdog_idle`` ini option [s]: with no test running, this long without any
#: event from a worker is a hang (a worker's collection or its session teardown takes seconds).
IDLE_S = 120.0
#: How often the watchdog looks [s].
PERIOD_S = 1.0
#: Ceilings, once the watchdog has fired: for one ``py-spy dump``, for the killed processes to be
#: gone, and for the main thread to end the run after its workers are gone (then it is interrupted,
#: and past a second ceiling the process exits).
DUMP_S, GONE_S, END_S = 30.0, 30.0, 60.0
#: How many never-run tests the summary names.
NAMED = 20


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini("watchdog_idle", f"seconds without any event from a worker, no test running, "
                                   f"before the run is ended as hung (default {IDLE_S:g})",
                  default=str(IDLE_S))


class Watchdog:
    """The controller's view of the run: the tests in flight and the time of the last event."""

    def __init__(self, idle_s: float, ceiling_s: float, out: TextIO) -> None:
        #: a test whose own ceiling the controller has not heard yet (before its setup report) has
        #: the run's; inf: none
        self.idle_s, self.ceiling_s, self.out = idle_s, ceiling_s, out
        self.lock = threading.Lock()
        self.last = time.monotonic()
        self.last_event = "the run started"
        self.in_flight: dict[str, float] = {}  # node id → its ceiling [s]
        self.started = False  # the first test has started: the workers have collected
        self.collected: list[str] = []
        self.reported: set[str] = set()
        self.fired: str | None = None
        self.ended = threading.Event()
        self.thread = threading.Thread(target=self._watch, name="suite-watchdog", daemon=True)

    def event(self, what: str, started: str | None = None, finished: str | None = None,
              ceiling: tuple[str, float] | None = None) -> None:
        with self.lock:
            self.last, self.last_event = time.monotonic(), what
            if started:
                self.in_flight[started] = self.ceiling_s
                self.started = True
            if finished:
                self.in_flight.pop(finished, None)
            if ceiling and ceiling[0] in self.in_flight:
                self.in_flight[ceiling[0]] = ceiling[1]

    def limit(self) -> float:
        """How long the run may be quiet now [s] (with the lock held): no test running, the idle
        limit; tests running, the longest of their ceilings plus it."""
        if not self.in_flight:
            return self.idle_s if self.started else self.ceiling_s + self.idle_s
        return max(self.in_flight.values()) + self.idle_s

    def _watch(self) -> None:
        while not self.ended.wait(PERIOD_S):  # a sampling period, not a wait for a state
            with self.lock:
                quiet = time.monotonic() - self.last
                idle = self.started and not self.in_flight
                if quiet <= self.limit():
                    continue
                what = "no test running" if idle else f"{len(self.in_flight)} test(s) in flight"
                self.fired = (f"{what} and no event from any worker for {quiet:.0f} s "
                              f"(the last: {self.last_event})")
                in_flight = sorted(self.in_flight)
            self._end_the_run(in_flight)
            return

    def _end_the_run(self, in_flight: list[str]) -> None:
        """Print what every process of the run is doing, kill the workers' trees, end the run."""
        write = self.out.write
        write(f"\n{'!' * 30} watchdog: the run is hung {'!' * 30}\n{self.fired}\n"
              f"tests in flight: {', '.join(in_flight) or 'none'}\n\n"
              f"the controller (pid {os.getpid()}):\n")
        self.out.flush()
        faulthandler.dump_traceback(file=self.out, all_threads=True)
        processes = psutil.Process().children(recursive=True)
        for process in processes:
            _describe(process, self.out)
        write(f"watchdog: killing {len(processes)} processes; the run ends\n")
        self.out.flush()
        for process in processes:
            with contextlib.suppress(psutil.Error):  # ended since it was listed
                process.kill()
        psutil.wait_procs(processes, timeout=GONE_S)
        # xdist sees its workers go down and ends the run (--max-worker-restart=0); if its main
        # loop does not, it is interrupted, and then the process ends
        if not self.ended.wait(END_S):
            _thread.interrupt_main()
            if not self.ended.wait(END_S):
                write("watchdog: the run did not end after an interrupt; exiting\n")
                self.out.flush()
                os._exit(pytest.ExitCode.INTERNAL_ERROR)

    def never_run(self) -> list[str]:
        return [nodeid for nodeid in self.collected if nodeid not in self.reported]


def _describe(process: psutil.Process, out: TextIO) -> None:
    """One line on the process, then its Python stack where it is a Python process."""
    try:
        with process.oneshot():
            times = process.cpu_times()
            command = " ".join(process.cmdline())
            out.write(f"\npid {process.pid} (parent {process.ppid()}) {process.status()}, "
                      f"{times.user + times.system:.1f} CPU-s: {command[:300]}\n")
            python = "python" in process.name()
    except psutil.Error as exc:
        out.write(f"\npid {process.pid}: {exc!r}\n")
        return
    out.flush()
    spy = shutil.which("py-spy") or shutil.which("py-spy", path=os.path.dirname(sys.executable))
    if python and spy:
        try:
            subprocess.run([spy, "dump", "--pid", str(process.pid)], stdout=out, stderr=out,
                           timeout=DUMP_S, check=False)
        except subprocess.TimeoutExpired:
            out.write(f"(py-spy dump of {process.pid} took over {DUMP_S:g} s)\n")
    elif python:
        out.write("(no py-spy: its Python stack is not shown)\n")


#: The watchdog of this run (None: not an xdist controller).
_current: Watchdog | None = None
#: In an xdist worker, the run's stderr (None elsewhere).
_worker_stderr: TextIO | None = None


def _stderr() -> TextIO:
    """fd 2 as it is at configure time (capture is suspended): the terminal, whatever captures later;
    closed at unconfigure."""
    return os.fdopen(os.dup(2), "w", buffering=1)


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config: pytest.Config) -> None:
    """Watches the run in an xdist controller (not in its workers, not in a run without xdist,
    where pytest-timeout ends a hung test and nothing else is shared); there a crashed worker is
    not replaced unless ``--max-worker-restart`` says so (set before xdist's own configure reads
    it)."""
    global _current, _worker_stderr
    if hasattr(config, "workerinput"):
        _worker_stderr = _stderr()
        return
    if not getattr(config.option, "numprocesses", None):
        return
    if config.option.maxworkerrestart is None:
        config.option.maxworkerrestart = "0"
    _current = Watchdog(float(config.getini("watchdog_idle")), run_ceiling(config), _stderr())
    _current.thread.start()


def run_ceiling(config: pytest.Config) -> float:
    """pytest-timeout's ceiling for a test of this run [s]: ``--timeout`` when given (0: none, inf
    here), else the ini's; inf without pytest-timeout."""
    if not config.pluginmanager.hasplugin("timeout"):
        return float("inf")
    given = config.getoption("timeout", None)
    seconds = float(given if given is not None else config.getini("timeout") or 0)
    return seconds if seconds > 0 else float("inf")


#: In an xdist worker: the ceiling pytest-timeout set for a test (none set: it has none).
CEILING = pytest.StashKey[float]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """In an xdist worker: the setup report carries the test's ceiling, as pytest-timeout resolved
    it (its mark's or the run's), to the controller's watchdog (a report's extra attributes travel
    with it)."""
    outcome = yield
    if _worker_stderr is not None and call.when == "setup":
        outcome.get_result().ceiling_s = item.stash.get(CEILING, float("inf"))


def pytest_unconfigure() -> None:
    global _current, _worker_stderr
    if _current is not None:
        _current.ended.set()
        _current.out.close()
        _current = None
    if _worker_stderr is not None:
        _worker_stderr.close()
        _worker_stderr = None


@pytest.hookimpl(tryfirst=True, optionalhook=True)  # pytest-timeout's hook
def pytest_timeout_set_timer(item: pytest.Item, settings) -> bool | None:
    """In an xdist worker: at pytest-timeout's ceiling, every thread's stack to the run's stderr and
    the worker's end (xdist then reports the test as the one its worker crashed in)."""
    if _worker_stderr is None:
        return None
    item.stash[CEILING] = settings.timeout
    faulthandler.dump_traceback_later(settings.timeout, exit=True, file=_worker_stderr)
    return True


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_timeout_cancel_timer(item: pytest.Item) -> bool | None:
    if _worker_stderr is None:
        return None
    faulthandler.cancel_dump_traceback_later()
    return True


def pytest_runtest_logstart(nodeid: str) -> None:
    if _current is not None:
        _current.event(f"{nodeid} started", started=nodeid)


def pytest_runtest_logfinish(nodeid: str) -> None:
    if _current is not None:
        _current.event(f"{nodeid} finished", finished=nodeid)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if _current is not None:
        _current.reported.add(report.nodeid)
        ceiling = getattr(report, "ceiling_s", None)
        _current.event(f"{report.nodeid} {report.when} {report.outcome}",
                       ceiling=(report.nodeid, ceiling) if ceiling is not None else None)


@pytest.hookimpl(optionalhook=True)  # xdist's hook
def pytest_handlecrashitem(crashitem: str) -> None:
    if _current is not None:
        _current.event(f"the worker running {crashitem} crashed", finished=crashitem)


@pytest.hookimpl(optionalhook=True)  # xdist's hook
def pytest_testnodedown(node, error) -> None:
    if _current is not None:
        _current.event(f"worker {node.gateway.id} down" + (f": {error}" if error else ""))


@pytest.hookimpl(optionalhook=True)  # xdist's hook
def pytest_xdist_node_collection_finished(node, ids: list[str]) -> None:
    if _current is not None:
        _current.collected = _current.collected or list(ids)
        _current.event(f"worker {node.gateway.id} collected {len(ids)} tests")


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session: pytest.Session) -> None:
    """A run that the watchdog ended, or that never ran some of its tests, does not pass."""
    watchdog = _current
    if watchdog is None:
        return
    watchdog.ended.set()
    if watchdog.fired is not None:
        session.exitstatus = pytest.ExitCode.INTERRUPTED
    elif watchdog.never_run() and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter) -> None:
    watchdog = _current
    if watchdog is None:
        return
    if watchdog.fired is not None:
        terminalreporter.write_sep("!", f"watchdog ended the run: {watchdog.fired}", red=True)
    never = watchdog.never_run()
    if never:
        terminalreporter.write_sep("!", f"{len(never)} of {len(watchdog.collected)} collected tests "
                                        f"never ran", red=True)
        for nodeid in never[:NAMED]:
            terminalreporter.write_line(f"never ran: {nodeid}")
        if len(never) > NAMED:
            terminalreporter.write_line(f"… and {len(never) - NAMED} more")
