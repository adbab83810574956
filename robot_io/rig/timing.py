"""The rig's timing, watched from its own sample stream: how late the control loop's cycles start and
how old the hand samples it steers by are, reported as soon as either runs late, before trials fail.

Trials fail on timing at ``[loop] staleness_limit_s`` (0.1 s by default: a hand sample that old is a
lost tracker, and a UR's watchdog stops the program when no target comes for 1/watchdog_hz, 0.1 s by
default). A busy machine gets there in steps: cycles a few to tens of milliseconds late, hand samples
older and older. The watch warns at a share of that limit: a cycle late by more than
``LATE_CYCLE_SHARE`` of it (and by at least ``LATE_CYCLE_PERIODS`` periods), a hand sample older
than ``OLD_SAMPLE_SHARE`` of it when a cycle used it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from robot_io.config import LoopConfig
from robot_io.control.recorder import SLICES
from robot_io.rig.messages import RigTiming
from robot_io.rig.stream import SampleStream

#: A cycle late by more than this share of staleness_limit_s is reported (0.01 s by default) ...
LATE_CYCLE_SHARE = 0.1
#: ... and by at least this many periods (a cycle or two late is the normal policy's jitter).
LATE_CYCLE_PERIODS = 2
#: A hand sample older than this share of staleness_limit_s when a cycle used it is reported.
OLD_SAMPLE_SHARE = 0.5
#: How often the watch reads the stream [s], and how often at most it reports one trial again.
WATCH_S, REPORT_AGAIN_S = 0.1, 1.0


class TimingWatch:
    """Reads the rows a trial has written since the last look and keeps the trial's worst: late
    cycles, the latest start, the oldest hand sample used. :meth:`check` returns a
    :class:`RigTiming` when one of them is past its bound and the trial's figures grew since the
    last report (at most every REPORT_AGAIN_S), else None."""

    def __init__(self, loop: LoopConfig, realtime_priority: bool) -> None:
        self.late_bound_s = max(LATE_CYCLE_SHARE * loop.staleness_limit_s,
                                LATE_CYCLE_PERIODS / loop.rate_hz)
        self.old_bound_s = OLD_SAMPLE_SHARE * loop.staleness_limit_s
        self.staleness_limit_s = loop.staleness_limit_s
        self.realtime_priority = realtime_priority
        self._trial = -1
        self._start_trial(-1)

    def _start_trial(self, trial_index: int) -> None:
        self._trial, self._seen = trial_index, 0
        self._late, self._latest, self._oldest = 0, 0.0, 0.0
        self._reported: tuple[int, float, float] | None = None
        self._reported_at = -np.inf

    def check(self, stream: SampleStream, final: bool = False) -> RigTiming | None:
        """``final``: the trial has ended (its rows are all written): its whole figures, at once
        and even if they were reported already, marked final — what the terminal and the dashboard
        both keep of the trial."""
        if stream.trial_index != self._trial:
            self._start_trial(stream.trial_index)
        # while the trial runs, the last row counted may still be being written
        rows = stream.rows_of(self._trial, self._seen, finished_only=not final)
        if len(rows):
            self._seen += len(rows)
            lateness = rows[:, SLICES["lateness_s"]].ravel()
            age = (rows[:, SLICES["t"]] - rows[:, SLICES["hand_t"]]).ravel()
            late = lateness[lateness > self.late_bound_s]
            self._late += len(late)
            self._latest = max(self._latest, float(late.max(initial=0.0)))
            self._oldest = max(self._oldest, float(np.nanmax(age, initial=0.0)))
        figures = (self._late, self._latest, self._oldest)
        degraded = self._late > 0 or self._oldest > self.old_bound_s
        now = time.monotonic()
        if not degraded or (not final and (figures == self._reported
                                           or now - self._reported_at < REPORT_AGAIN_S)):
            return None
        self._reported, self._reported_at = figures, now
        return RigTiming(trial_index=self._trial, late_cycles=self._late,
                         latest_start_s=self._latest, late_bound_s=self.late_bound_s,
                         oldest_hand_sample_s=self._oldest, old_bound_s=self.old_bound_s,
                         staleness_limit_s=self.staleness_limit_s,
                         realtime_priority=self.realtime_priority, final=final)


class TimingReporter:
    """Checks the stream every WATCH_S on a thread of its own and sends what the watch reports,
    and the whole trial's figures at its end (:meth:`trial_ended`, before the trial's end is
    reported), until :meth:`close` (before the stream is closed: a look may hold its rows
    meanwhile). The watch is the reporter's: one look at a time, under its lock."""

    def __init__(self, stream: SampleStream, watch: TimingWatch,
                 send: Callable[[RigTiming], None]) -> None:
        self._stream, self._watch, self._send = stream, watch, send
        self._looking = threading.Lock()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rig-timing", daemon=True)
        self._thread.start()

    def _look(self, final: bool) -> None:
        with self._looking:
            timing = self._watch.check(self._stream, final)
        if timing is not None:
            self._send(timing)

    def _run(self) -> None:
        while not self._closed.wait(WATCH_S):
            self._look(final=False)

    def trial_ended(self) -> None:
        """The trial's rows are all written: its whole figures, if its timing was degraded."""
        self._look(final=True)

    def close(self) -> None:
        self._closed.set()
        self._thread.join()
