"""The study's Lab Streaming Layer outlets (``[record] lsl_outlets``), for the lab's own recording
(LabRecorder → XDF, next to its eye tracker, EEG, ...; docs/hardware.md, "The study's LSL outlets").

- ``<lsl_name>-robot`` (type ``HandoverRobot``): one sample per control cycle while a trial streams
  (Go to the end of the hold), at the control rate (125 Hz CB-series, 500 Hz e-Series): the trial
  index, the measured TCP, the joint angles q, the DMP phase s, the filtered distance d̃ (eq. 7),
  C_t (eq. 8) and the sample's stage code. The control loop never sees LSL: a feed thread of the
  application reads the rows the rig writes into shared memory (:mod:`robot_io.rig.stream`) and
  pushes them with their own time, Go's ``time.monotonic()`` + the row's ``t``.
- ``<lsl_name>-markers`` (type ``Markers``): one JSON marker per stored event of the study
  (:mod:`app.protocol.markers`), stamped with the event's stored time.

Both time stamps are in the LSL clock: ``pylsl.local_clock()`` is CLOCK_MONOTONIC on Linux, the
clock of ``time.monotonic()``, and a stored UTC time is mapped onto it with
:func:`robot_io.clock.monotonic_of_utc`. The stream's ``desc`` carries the participant code; the
``source_id`` adds it and the session's creation time to the name, so two sessions never share one.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

import numpy as np
import pylsl

from app.protocol import events as ev
from app.protocol.markers import MARKER_TYPE, ROBOT_TYPE, SOFTWARE, encode, marker
from app.protocol.state import SessionState
from app.session.config import RecordSettings
from robot_io.clock import monotonic_of_utc
from robot_io.control.recorder import SLICES
from robot_io.rig.stream import SampleStream

log = logging.getLogger(__name__)

#: The robot stream's channels: (sample column, channel labels, unit; "1": dimensionless).
ROBOT_COLUMNS: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("measured", ("tcp_x", "tcp_y", "tcp_z"), "m"),
    ("q", tuple(f"q{joint}" for joint in range(6)), "rad"),
    ("s", ("phase",), "1"),
    ("d_filtered", ("d_filtered",), "m"),
    ("c_t", ("c_t",), "1"),
    ("stage", ("stage",), "code: 1 reach, 2 hold, 3 released"),
)
#: The first channel is the trial index; the rest are these columns of a sample row, in order.
ROBOT_INDEX = np.concatenate([np.arange(SLICES[c].start, SLICES[c].stop) for c, _, _ in ROBOT_COLUMNS])
ROBOT_CHANNELS = (("trial", "index"), *((label, unit) for _, labels, unit in ROBOT_COLUMNS
                                         for label in labels))
#: How often the feed looks for new rows [s]: a few control cycles per chunk.
FEED_POLL_S = 0.02
T = SLICES["t"].start


def stream_info(name: str, kind: str, channels: tuple[tuple[str, str], ...], rate_hz: float,
                fmt: int, source_id: str, code: str) -> pylsl.StreamInfo:
    """A stream's description: the participant code and each channel's label and unit in ``desc``."""
    info = pylsl.StreamInfo(name, kind, len(channels), rate_hz, fmt, source_id)
    desc = info.desc()
    desc.append_child_value("participant", code)
    desc.append_child_value("software", SOFTWARE)
    described = desc.append_child("channels")
    for label, unit in channels:
        channel = described.append_child("channel")
        channel.append_child_value("label", label)
        channel.append_child_value("unit", unit)
    return info


class RobotFeed:
    """Pushes the rig's sample rows to the robot outlet from a thread of its own, every
    :data:`FEED_POLL_S`; :meth:`flush` pushes what is left of a finished trial at once."""

    def __init__(self, outlet: pylsl.StreamOutlet, samples: Callable[[], SampleStream | None]) -> None:
        self._outlet, self._samples = outlet, samples
        self._lock = threading.Lock()
        self._go: tuple[int, float] | None = None  # the streaming trial and its Go (monotonic)
        self._pushed = 0  # rows of that trial pushed so far
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lsl-robot-feed", daemon=True)
        self._thread.start()

    def go(self, trial_index: int, monotonic: float) -> None:
        """Trial ``trial_index`` began streaming at ``monotonic`` (its Go)."""
        with self._lock:
            self._go, self._pushed = (trial_index, monotonic), 0

    def flush(self) -> None:
        """Push every row written so far (all of a finished trial's)."""
        with self._lock:
            self._push()

    def close(self) -> None:
        self._stopping.set()
        self._thread.join()

    def _run(self) -> None:
        while not self._stopping.wait(FEED_POLL_S):
            self.flush()

    def _push(self) -> None:
        stream = self._samples()
        if stream is None or self._go is None:
            return
        trial, go = self._go
        rows = stream.rows_of(trial, self._pushed)  # none once the next trial began
        if len(rows) == 0:
            return
        self._pushed += len(rows)
        rows = rows[np.isfinite(rows[:, T])]
        chunk = np.column_stack([np.full(len(rows), float(trial)), rows[:, ROBOT_INDEX]])
        self._outlet.push_chunk(chunk, (go + rows[:, T]).tolist())


def outlet_names(settings: RecordSettings) -> tuple[str, str]:
    """The names of a session's robot and marker outlets: ``<lsl_name>-robot``, ``<lsl_name>-markers``."""
    return f"{settings.lsl_name}-robot", f"{settings.lsl_name}-markers"


class StudyOutlets:
    """The robot and marker outlets of one participant's session (open while it is open)."""

    def __init__(self, settings: RecordSettings, code: str, created_at: str, rate_hz: int,
                 samples: Callable[[], SampleStream | None]) -> None:
        session = f"{code}:{created_at}"
        self.robot_name, self.markers_name = outlet_names(settings)
        #: the streams' source_ids, which name this session (the session's recording finds them by it)
        self.source_ids = [f"{self.markers_name}:{session}", f"{self.robot_name}:{session}"]
        self._markers = pylsl.StreamOutlet(stream_info(
            self.markers_name, MARKER_TYPE, (("marker", "JSON"),), pylsl.IRREGULAR_RATE, pylsl.cf_string,
            self.source_ids[0], code))
        self._robot = pylsl.StreamOutlet(stream_info(
            self.robot_name, ROBOT_TYPE, ROBOT_CHANNELS, rate_hz, pylsl.cf_double64,
            self.source_ids[1], code))
        self.feed = RobotFeed(self._robot, samples)
        log.info("LSL outlets %r and %r for participant %s (%d Hz)", self.robot_name,
                 self.markers_name, code, rate_hz)

    def on_event(self, event: ev.ProtocolEvent, state: SessionState) -> None:
        """Push the marker of a stored event (an engine listener), stamped with its stored time."""
        content = marker(event, state)
        if content is not None:
            self._markers.push_sample([encode(content)], monotonic_of_utc(event.at))

    def close(self) -> None:
        self.feed.close()
        self._markers = self._robot = None  # liblsl closes an outlet when it is released
