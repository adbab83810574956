"""The rig process's main function: open the devices, then run one handover cycle per
:class:`~robot_io.rig.messages.RunTrial` until told to shut down or until the application is gone.

Its main thread runs the control loop; with ``realtime_priority`` (``[loop] realtime_priority``,
"auto" by default, ``--[no-]realtime-priority``) the whole process runs under SCHED_FIFO where the
OS allows it (on the wall clock; it says in its
:class:`~robot_io.rig.messages.DeviceReport` whether it does);
an inbox thread receives commands, so a Stop reaches the running loop within one cycle. When the
pipe to the application closes (the application exited or was killed), the arm is stopped and the
process exits; when this process dies, the UR's control worker sees its pipe close and stops the arm
(servoStop, stopScript), and the controller's watchdog stops the program anyway. A thread reports
the tracked hand's link notice (:class:`~robot_io.rig.messages.HandLink`) each time it changes.
"""

from __future__ import annotations

import contextlib
import faulthandler
import gc
import logging
import math
import os
import queue
import signal
import threading
import time
from multiprocessing.connection import Connection

from robot_io.child_signals import ignore_interrupts
from robot_io.clock import SUPPORT_PRIORITY, raise_priority
from robot_io.control.cycle import Gates, run_cycle
from robot_io.errors import RobotIOError, explain
from robot_io.hands.tracked_hand import Link, TrackedHand
from robot_io.rig.devices import RigDevices
from robot_io.rig.messages import (
    APP_SILENCE_S,
    HEARTBEAT_S,
    Gate,
    HandLink,
    ReadyWaiting,
    Recover,
    Recovered,
    Report,
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
from robot_io.rig.silence import WatchedSilence
from robot_io.rig.stream import SampleStream, StreamRecorder
from robot_io.rig.timing import TimingReporter, TimingWatch

log = logging.getLogger(__name__)

#: How often the rig looks whether the tracked hand's link notice changed [s].
LINK_REPORT_S = 0.25

#: The application sends it to a rig it is about to kill: every thread's stack goes to stderr.
STACKS_SIGNAL = signal.SIGUSR1


class Outbox:
    """Sends reports from any thread of the rig (one at a time)."""

    def __init__(self, conn: Connection) -> None:
        self._conn, self._lock = conn, threading.Lock()

    def send(self, report: Report) -> None:
        # if the application is gone the inbox sees it and shuts the rig down
        with self._lock, contextlib.suppress(OSError, ValueError):
            self._conn.send(report)


#: Process states (``/proc/<pid>/stat``) of a process that a signal has stopped: 'T' (SIGSTOP,
#: SIGTSTP from Ctrl-Z) and 't' (stopped by a debugger's trace).
STOPPED_STATES = frozenset("Tt")


def process_state(pid: int) -> str | None:
    """The kernel's one-letter state of process ``pid`` (R running, S sleeping, T stopped, ...);
    None where there is no ``/proc`` (not Linux) or no such process. It needs nothing from that
    process: a frozen interpreter cannot hide it."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            # "pid (comm) state ...": comm may hold spaces and parentheses, the state follows the last ')'
            return stat.read().rpartition(b")")[2].split()[0].decode()
    except (OSError, IndexError):
        return None


class Inbox:
    """Receives commands: RunTrial and Shutdown are queued for the main thread; Gate and Stop act at
    once on the running trial's gates (a Stop between trials stops the arm here). With
    ``watch_application`` (trials on the wall clock) it also stops a running trial's arm when the
    application is stopped by a signal, or has sent nothing, not even a :class:`Heartbeat`, for
    ``APP_SILENCE_S``."""

    def __init__(self, conn: Connection, outbox: Outbox, devices: RigDevices,
                 watch_application: bool) -> None:
        self._conn, self._outbox, self._devices = conn, outbox, devices
        self._cycle = devices.spec.cycle
        self._watch_application = watch_application
        self.commands: queue.Queue[tuple[RunTrial, Gates] | Recover | None] = queue.Queue()
        self.gates: Gates | None = None
        self.running = False
        #: the application's silence (the inbox thread owns it)
        self._silence = WatchedSilence(HEARTBEAT_S / 2, time.monotonic())
        self._application = os.getppid()  # the process that started the rig (spawn)
        threading.Thread(target=self._receive, name="rig-inbox", daemon=True).start()

    def _receive(self) -> None:
        while True:
            try:
                # a message already waiting is read before the silence is judged, and the time
                # this thread was itself not run is not the application's (robot_io.rig.silence)
                asked = time.monotonic()
                if not self._conn.poll(HEARTBEAT_S / 2):
                    self._silence.looked(asked, time.monotonic())
                    self._check_application()
                    continue
                command = self._conn.recv()
            except (EOFError, OSError):
                log.warning("the application is gone: stopping the arm and exiting")
                self._stop("the application is gone")
                self.commands.put(None)
                return
            self._silence.heard(time.monotonic())
            if isinstance(command, RunTrial):
                gates = Gates.of(self._cycle, automatic=command.automatic)
                self.gates = gates
                self.commands.put((command, gates))
            elif isinstance(command, Gate) and self.gates is not None:
                self.gates.confirm(command.stage)
            elif isinstance(command, Stop):
                self._outbox.send(StopReceived())
                self._stop(command.reason)
            elif isinstance(command, Recover):
                self.commands.put(command)
            elif isinstance(command, Shutdown):
                self._stop("the rig was shut down")
                self.commands.put(None)
                return

    def _check_application(self) -> None:
        """Stop the running trial's arm if the application is frozen: stopped by a signal, as its
        process state says (at once), or silent for APP_SILENCE_S while the rig watched (it hangs)."""
        now, gates = time.monotonic(), self.gates
        silent = self._silence.silent(now)
        if not self._watch_application or not self.running or gates is None or gates.stop.is_set():
            return
        if (state := process_state(self._application)) in STOPPED_STATES:
            reason = (f"the application is stopped (Ctrl-Z, SIGSTOP or a debugger: process state "
                      f"{state}) and sent nothing for {silent:.2f} s: the rig stopped the arm")
        elif self._silence.watched(now) > APP_SILENCE_S:
            held = (f", {self._silence.unwatched:.2f} s of it while the rig itself was held still"
                    if self._silence.unwatched >= HEARTBEAT_S else "")
            reason = (f"the application sent nothing for {silent:.2f} s{held} (APP_SILENCE_S = "
                      f"{APP_SILENCE_S:g} s: it hangs): the rig stopped the arm")
        else:
            return
        log.error("%s", reason)
        gates.stop.request(reason)

    def _stop(self, reason: str) -> None:
        if self.gates is not None:
            self.gates.stop.request(reason)  # a running (or queued) cycle stops the arm within one cycle
        if not self.running:
            self._devices.stop_arm()


def report_link(link: Link, outbox: Outbox) -> None:
    """Send ``link``'s notice each time it changes (a daemon thread's loop, for the rig's life)."""
    said = None
    while True:
        time.sleep(LINK_REPORT_S)  # pacing a look, not waiting for a state
        if (notice := link.notice()) is not None and notice != said:
            outbox.send(HandLink(notice=notice))
            said = notice


def main(conn: Connection, spec: RigSpec, stream_name: str, capacity: int, log_level: int) -> None:
    """Entry point of the rig process (``multiprocessing`` spawn); logs at the application's level."""
    logging.basicConfig(level=log_level, format=f"rig[{os.getpid()}] %(levelname)s %(name)s: %(message)s")
    faulthandler.register(STACKS_SIGNAL, all_threads=True)
    # Ctrl-Z in the application's terminal stops its whole process group: the rig (and ur_rtde's
    # control worker, which inherits this) stays running, sees its application stopped and stops the
    # arm itself (Inbox), rather than being frozen mid-reach with it
    signal.signal(signal.SIGTSTP, signal.SIG_IGN)
    # Ctrl-C, too, reaches the whole group: it is the application's to act on (it stops the arm
    # through this rig, then closes it); here it was a KeyboardInterrupt that ended the loop
    # mid-cycle and printed a traceback. Held since the start (RigClient), now dropped; ur_rtde's
    # control worker inherits this as well.
    ignore_interrupts()
    outbox = Outbox(conn)
    # every thread of the rig inherits it (the hand receiver, ur_rtde's, the inbox); the loop's own
    # thread runs above them while a trial runs (RealClock.start)
    raised = spec.realtime and spec.realtime_priority and raise_priority(SUPPORT_PRIORITY) is not None
    try:
        devices = RigDevices(spec)
    except (RobotIOError, OSError, ValueError) as exc:
        outbox.send(RigFailed(reason=explain(exc)))
        return
    stream = SampleStream(capacity, name=stream_name)
    gc.freeze()  # what the rig holds from here on is never scanned by a collection again
    inbox = Inbox(conn, outbox, devices, watch_application=spec.realtime)
    timing = (TimingReporter(stream, TimingWatch(devices.config.loop, raised), outbox.send)
              if spec.realtime else None)
    outbox.send(RigOpened(devices=devices.report().model_copy(update={"realtime_priority": raised}),
                          pid=os.getpid()))
    if isinstance(devices.tracked, TrackedHand):
        threading.Thread(target=report_link, args=(devices.tracked.link, outbox), name="rig-link",
                         daemon=True).start()
    try:
        while (item := inbox.commands.get()) is not None:
            if isinstance(item, Recover):
                try:
                    outbox.send(Recovered(ok=True, message=devices.recover(item.inspected)))
                except RobotIOError as exc:
                    outbox.send(Recovered(ok=False, message=explain(exc)))
                continue
            command, gates = item
            _run(command, gates, devices, stream, outbox, inbox, timing)
    finally:
        if timing is not None:
            timing.close()
        devices.close()
        stream.close()


def _run(command: RunTrial, gates: Gates, devices: RigDevices, stream: SampleStream,
         outbox: Outbox, inbox: Inbox, timing: TimingReporter | None) -> None:
    index = command.trial_index

    def on_stage(stage: str, t: float) -> None:
        outbox.send(StageReached(trial_index=index, stage=stage, t=None if math.isnan(t) else t,
                                 monotonic=time.monotonic()))

    recorder = StreamRecorder(stream, index)
    inbox.running = True
    try:
        record = run_cycle(devices.config, command.theta, devices.for_trial(command.hand_seed),
                           gates, on_stage, recorder,
                           on_waiting=lambda why: outbox.send(ReadyWaiting(trial_index=index, why=why)),
                           cycle=devices.spec.cycle)
    finally:
        inbox.running = False
    if timing is not None:
        timing.trial_ended()  # the whole trial's figures, before its end: the screens keep them
    outbox.send(TrialDone(trial_index=index, summary=record.summary, rows=recorder.count))
