"""The application's handle on the rig process: start it, send commands, hear its reports, read its
samples, and stop the arm even when the rig itself no longer answers.

Stop has two paths. The normal one is a :class:`~robot_io.rig.messages.Stop` message: the loop
stops the arm within one cycle. If the rig does not acknowledge it within ``STOP_ACK_S`` (the loop
is stuck, the process hangs), :meth:`RigClient.backstop` acts without it: on a UR it sends the
controller's dashboard ``stop`` (the program ends and the arm halts; the control script's watchdog
would end it anyway within 1/watchdog_hz), and it kills the rig process. The same backstop fires by
itself when the rig stops writing samples for ``HANG_S`` while it streams. The other way round,
the same watchdog thread sends the rig a heartbeat during a trial: a rig that hears nothing from a
frozen application for ``APP_SILENCE_S`` stops the arm (robot_io.rig.process.Inbox).

Lifetimes (docs/architecture.md, "Shared objects and their lifetimes"): the client creates the
sample stream, the pipe, the dashboard connection and its two threads. The pipe is closed by the
reader alone, once the rig's end is gone. The sample stream has two holders, :meth:`RigClient.close`
and the reader (which reads a trial's rows when it hands on the trial's end): the second of them to
be done releases it, so no report is ever handed on with its rows unmapped, and close() never waits
for the reader (which may itself wait for the thread that closes). The watchdog is joined by close().
The rig's process handle (its sentinel and the pipe its start was sent down) is used by close(),
kill() (the backstop, from the watchdog or a Stop), the reader (the exit code of a dead rig) and
the screens (:attr:`RigClient.alive`), each under one lock; the same last holder releases it once
the rig is reaped, rather than leaving it to ``multiprocessing``, which kept a child whose exit code
was read but that was never joined (and its two pipes) until some later start.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import select
import threading
import time
from collections.abc import Callable

from robot_io.arms.arm import Backstop
from robot_io.child_signals import interrupts_held
from robot_io.clock import SUPPORT_PRIORITY, raise_priority
from robot_io.errors import RobotIOError
from robot_io.rig import process
from robot_io.rig.messages import (
    HEARTBEAT_S,
    Command,
    DeviceReport,
    Gate,
    Heartbeat,
    Recover,
    Recovered,
    Report,
    RigDied,
    RigFailed,
    RigOpened,
    RigSpec,
    RunTrial,
    Shutdown,
    StageReached,
    Stop,
    StopReceived,
    TrialDone,
)
from robot_io.rig.silence import WatchedSilence, waited
from robot_io.rig.stream import SampleStream, capacity_for

log = logging.getLogger(__name__)

#: How long the rig may take to open its devices [s] (a UR connects, uploads its script).
OPEN_TIMEOUT_S = 30.0
#: A Stop not acknowledged within this long fires the backstop [s].
STOP_ACK_S = 0.3
#: While streaming, no new sample row for this long means the rig hangs [s].
HANG_S = 0.5
#: Before a trial's first row and after its last one, the rig waits on the arm with timeouts of its
#: own: starting the stream may re-upload the control script ([ur] connect_timeout_s), and the stop
#: sends servoStop and stopScript (1 s each), then waits up to 1 s for the arm to rest: 3 s at
#: most, and 2 s of margin. Silence longer than this (after connect_timeout_s, when starting) means
#: the rig hangs [s]. A UR's own watchdog stops the arm 0.1 s after the last servo target anyway.
SETTLE_S = 5.0
#: How long the application waits to see a dead or killed rig's exit code [s] (1 s was too short under load).
REAP_S = 5.0
#: The longest the handle's lock is held while the rig is joined [s] (a screen asking whether the
#: rig is alive waits at most this long).
REAP_SLICE_S = 0.02
#: How long a rig may take to stop the arm, release its devices and exit after Shutdown [s].
CLOSE_S = 5.0
#: How long a hung rig gets to print its threads' stacks before it is killed [s].
STACKS_S = 0.2


class RigError(RobotIOError):
    """The rig process could not be started or is gone."""


#: Hears each report with the client it came from (its sample stream is readable during the call).
Listener = Callable[["RigClient", Report | RigDied], None]


class RigClient:
    """Starts the rig process for ``spec`` and waits until its devices are open (or raises
    :class:`RigError` with the rig's reason). ``listener`` hears every report on a reader thread,
    and a :class:`RigDied` if the process ends without being told to."""

    def __init__(self, spec: RigSpec, listener: Listener) -> None:
        self.spec, self._listener = spec, listener
        # a real arm's rate (a UR's 125 or 500 Hz) may be known only once connected: room for the fastest
        rate = spec.config.arm.fastest_rate_hz or spec.config.loop.rate_hz
        self.stream = SampleStream(capacity_for(spec.config, rate))
        self._holders, self._holders_lock = 1, threading.Lock()  # of the stream: see _let_go
        # held for every use of the rig process handle (self._process: close(), kill(), the reader,
        # the screens) and for its release by the last holder (_release_handle)
        self._handle_lock = threading.Lock()
        self._exit_code: int | None = None  # kept when the handle is released (see _released)
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        # not a daemon: the rig starts its own child (the ur_rtde control worker)
        self._process = context.Process(target=process.main, name="handover-rig",
                                        args=(child, spec, self.stream.name, self.stream.capacity,
                                              logging.getLogger().getEffectiveLevel()))
        with interrupts_held():  # until the rig ignores them (child_signals)
            self._process.start()
        child.close()
        self.stage: str | None = None
        self.running: int | None = None  # the trial index the rig is running
        self._closing = False  # close() has begun: the rig's end is expected, not a death
        self._stop_ack = threading.Event()
        self._recovered = threading.Event()
        self._recovery: Recovered | None = None
        self._send_lock = threading.Lock()
        self._stopper: Backstop | None = None
        try:
            self.devices = self._await_open()
        except BaseException:
            self.kill()
            self._conn.close()  # no reader yet
            self._let_go()
            raise
        self._holders = 2  # close() and the reader, which hands on each trial's rows
        self._reader = threading.Thread(target=self._read, name="rig-reader", daemon=True)
        self._reader.start()
        self._watchdog = threading.Thread(target=self._watch, name="rig-watchdog", daemon=True)
        self._watchdog.start()

    # -- starting ----------------------------------------------------------------------------------
    def _await_open(self) -> DeviceReport:
        if not self._conn.poll(OPEN_TIMEOUT_S):
            raise RigError(f"the rig process did not open its devices within {OPEN_TIMEOUT_S} s")
        try:
            report = self._conn.recv()
        except (EOFError, OSError) as exc:
            raise RigError(f"the rig process exited while opening its devices (exit code "
                           f"{self.exit_code})") from exc
        if isinstance(report, RigFailed):
            raise RigError(f"the rig could not open its devices: {report.reason}")
        assert isinstance(report, RigOpened), report
        self._stopper = self.spec.config.arm.backstop(self.spec.config)
        return report.devices

    # -- commands ----------------------------------------------------------------------------------
    @property
    def alive(self) -> bool:
        with self._handle_lock:
            return self._runs()

    @property
    def pid(self) -> int | None:
        """The rig's process id; None once its handle is released (the number may be reused)."""
        with self._handle_lock:
            return None if self._released else self._process.pid

    @property
    def exit_code(self) -> int | None:
        """The rig's exit code (negative: the signal that ended it); None while it runs."""
        with self._handle_lock:
            return self._exit_code if self._released else self._process.exitcode

    @property
    def _released(self) -> bool:
        """The handle is released (its exit code kept, its pipes closed)."""
        return self._exit_code is not None

    def _runs(self) -> bool:
        """Whether the rig process runs; under the handle's lock."""
        return not self._released and self._process.is_alive()

    def _send(self, command: Command) -> bool:
        with self._send_lock:
            try:
                self._conn.send(command)
                return True
            except (OSError, ValueError):
                return False

    def run_trial(self, command: RunTrial) -> None:
        if not self.alive:
            raise RigError("the rig process is not running")
        self.running, self.stage = command.trial_index, None
        if not self._send(command):
            self.running = None
            raise RigError("the rig process is not reachable")

    def confirm(self, stage: str) -> None:
        """The experimenter's confirmation that ``stage`` waits for (Object loaded, Go, …)."""
        self._send(Gate(stage=stage))

    def recover(self, inspected: bool, timeout: float = 20.0) -> Recovered:
        """Ask the rig to clear the arm's fault (it waits out a UR's 5 s protective-stop rule)."""
        self._recovered.clear()
        if not self._send(Recover(inspected=inspected)):
            raise RigError("the rig process is not reachable")
        if not self._recovered.wait(timeout):
            raise RigError(f"the rig did not answer the recovery within {timeout} s")
        assert self._recovery is not None, "set before the answer is signalled"
        return self._recovery

    def stop(self, reason: str) -> bool:
        """Stop the arm. True if the rig acknowledged; otherwise the backstop fired."""
        self._stop_ack.clear()
        if self._send(Stop(reason=reason)) and self._acknowledged():
            return True
        self.backstop(f"the rig did not acknowledge Stop within {STOP_ACK_S} s")
        return False

    def _acknowledged(self) -> bool:
        """Whether the rig acknowledges the Stop within STOP_ACK_S of this thread's own waiting: a
        wait that comes back late (the machine held still, the rig with it) is not counted
        (robot_io.rig.silence), so a freeze of everything is not taken for a hung rig."""
        return waited(self._stop_ack.wait, STOP_ACK_S, STOP_ACK_S / 3)

    def backstop(self, why: str) -> None:
        """Stop the arm without the rig: the controller's own stop (UR), and kill the rig."""
        log.error("backstop: %s", why)
        if self._stopper is not None:
            self._stopper.stop()
        self._dump_stacks()
        self.kill()

    def _dump_stacks(self) -> None:
        """Have a hung rig print where each of its threads is (faulthandler, to its stderr: the
        application's log) before it is killed, so the hang can be found afterwards."""
        with self._handle_lock:
            pid = self._process.pid if self._runs() else None  # a closed handle has no pid
            if pid is None:
                return
            try:
                os.kill(pid, process.STACKS_SIGNAL)
            except OSError:
                return
        self._wait_reaped(STACKS_S)  # time to print them

    def kill(self) -> None:
        with self._handle_lock:
            if self._runs():
                self._process.kill()
        self._wait_reaped()

    def _wait_reaped(self, limit: float = REAP_S) -> bool:
        """Wait (at most ``limit`` s) until the rig is reaped; False if it is not by then. One
        thread at a time joins it, under the handle's lock (a few hundredths of a second at a
        time), so the report reader, close() and kill() no longer race for its exit code. It is
        *joined*, not only polled: ``multiprocessing`` forgets a child (and lets its handle go)
        only when a join sees it ended."""
        deadline = time.monotonic() + limit
        while True:
            with self._handle_lock:
                if self._released:
                    return True
                left = deadline - time.monotonic()
                self._process.join(min(max(left, 0.0), REAP_SLICE_S))
                if self._process.exitcode is not None:
                    # reaped by a poll (a start elsewhere polls every child) rather than by the
                    # join above: joined now, at once, so multiprocessing forgets it
                    self._process.join()
                    return True
            if left <= 0:
                return False

    def close(self) -> None:
        """Shut the rig down (it stops the arm and releases its devices); kill it if it hangs.
        From any thread but the watchdog; a second call does nothing."""
        if self._closing:
            return
        self._closing = True
        self._send(Shutdown())
        if not self._wait_reaped(CLOSE_S):
            log.error("the rig process did not exit within %g s: killing it", CLOSE_S)
            self.backstop("the rig did not shut down")
        # the pipe is not closed here: the reader closes it once the rig's end is gone (_read)
        self._watchdog.join()  # it ends within a heartbeat of _closing (or of the rig's end)
        if self._stopper is not None:
            self._stopper.close()
        self._let_go()

    def _let_go(self) -> None:
        """One holder of the sample stream is done with it (close(), or the reader at its end);
        the last one releases it. A read that another thread (a screen, the LSL feed) makes after
        that reads an empty stream (robot_io.rig.stream)."""
        with self._holders_lock:
            self._holders -= 1
            last = self._holders == 0
        if last:
            self.stream.close(unlink=True)
            self._release_handle()

    def _release_handle(self) -> None:
        """Close the rig's process handle (its two pipes) once it is reaped, keeping its exit
        code; one that could not be reaped (killed, yet not gone within REAP_S) is left open."""
        with self._handle_lock:
            code = self._process.exitcode
            if code is None:
                log.error("the rig process %d could not be reaped: its handle stays open",
                          self._process.pid)
                return
            self._exit_code = code
            self._process.close()

    def reports_handed_on(self, timeout: float = CLOSE_S) -> bool:
        """After :meth:`close`: wait until every report the rig sent (a stopped trial's end among
        them) has been handed on; False if that took longer than ``timeout``. Not from a thread the
        report listener itself waits for."""
        self._reader.join(timeout)
        return not self._reader.is_alive()

    # -- reports -----------------------------------------------------------------------------------
    def _read(self) -> None:
        """Hand every report on until the rig's end of the pipe is gone, then close the pipe. Only
        this thread closes it, and never while in ``recv``: a close() from another thread could land
        between recv's check that the pipe is open and its read, which would then read a handle gone
        None (the thread dies) or, had the number been reused, another file. Sends take the same
        lock, so none is under way when it closes."""
        try:
            try:
                self._hand_on()
            finally:
                with self._send_lock:
                    self._conn.close()
            self._wait_reaped()  # a killed rig is reported with its exit code
            if not self._closing:
                code = self.exit_code
                how = (f"killed by signal {-code}" if code is not None and code < 0
                       else f"exit code {code}")
                stage = self.stage
                self._notify(RigDied(trial_index=self.running, reason=(
                    f"the rig process ended ({how})" + (f" during {stage}" if stage else "")
                    + "; the arm was stopped by its control worker or the controller's watchdog")))
                self.running = None
        finally:
            self._let_go()

    def _hand_on(self) -> None:
        """Every report to what waits for it and to the listener, until the pipe ends."""
        while True:
            try:
                report = self._conn.recv()
            except (EOFError, OSError):
                return
            if isinstance(report, StopReceived):
                self._stop_ack.set()
            elif isinstance(report, Recovered):
                self._recovery = report
                self._recovered.set()
            elif isinstance(report, StageReached):
                self.stage = report.stage
            elif isinstance(report, TrialDone):
                self.running, self.stage = None, None
            self._notify(report)

    def _notify(self, report: Report | RigDied) -> None:
        try:
            self._listener(self, report)
        except Exception:
            log.exception("handling a rig report failed")

    def _silence_limit(self) -> tuple[float, str] | None:
        """How long the rig may write no sample row before it counts as hung, and what it is doing
        meanwhile; None while it is not watched (outside the streaming stages, simulated time)."""
        if self.stage not in self.spec.cycle.streamed or not self.spec.realtime:
            return None
        if self.stream.count == 0:
            return self.spec.config.ur.connect_timeout_s + SETTLE_S, "starting the stream"
        if self.stream.finished:
            return SETTLE_S, "stopping the arm"
        return HANG_S, "streaming"

    def _beat(self) -> None:
        """Tell a rig that runs a trial that the application is alive (robot_io.rig.messages
        .APP_SILENCE_S). Never blocks: a rig that has stopped reading (its pipe full) gets none, so
        a heartbeat can never hold up a Stop."""
        if self.running is None:
            return
        with self._send_lock, contextlib.suppress(OSError, ValueError):  # closed: no heartbeat
            if select.select([], [self._conn.fileno()], [], 0)[1]:
                self._conn.send(Heartbeat())

    def _watch(self) -> None:
        """Every HEARTBEAT_S: a heartbeat to the rig, and the backstop when the rig writes no sample
        row for longer than :meth:`_silence_limit` allows, not counting the time this thread itself
        was not run (robot_io.rig.silence). Runs under SCHED_FIFO where the OS allows it: this
        machine's load must not pass for a frozen application."""
        raise_priority(SUPPORT_PRIORITY)
        last_count, silence = -1, WatchedSilence(HEARTBEAT_S, time.monotonic())
        while self.alive and not self._closing:
            asked = time.monotonic()
            time.sleep(HEARTBEAT_S)
            self._beat()
            count, limit, now = self.stream.count, self._silence_limit(), time.monotonic()
            silence.looked(asked, now)
            if count != last_count or limit is None:
                last_count = count
                silence.heard(now)
            elif silence.watched(now) > limit[0]:
                self.backstop(f"the rig wrote no sample for {limit[0]:g} s while {limit[1]} "
                              f"({self.stage})")  # None if the trial just ended
                return
