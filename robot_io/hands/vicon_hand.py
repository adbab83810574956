# ruff: noqa: N802  (the client's methods keep the names of Vicon's own Python API: GetFrame, ...)
"""A hand source reading Vicon's DataStream (Tracker, Nexus, Shogun) through the Vicon DataStream SDK.

Which segment: ``[hand_source] vicon_segment`` of the subject ``vicon_subject``, both by name, never
"the first one streamed". At connection a name that no subject (or no segment of the subject) has, or
that more than one has, is refused with the names that exist; a subject that leaves the stream later
(disabled in Tracker) is a lost hand.

Samples: the segment's global translation in millimetres (the SDK's unit; ``units_to_m`` is 0.001),
put through the tracker → robot-base transform. A segment the SDK reports as occluded (its translation
is then zeros) is a lost hand: a NaN sample, never a position.

Time stamps: the instant a frame was first seen on ``time.monotonic`` minus the SDK's total latency
(``GetLatencyTotal``: the server's pipeline stages plus the network transmission the SDK measures;
0.0 when the server reports none: the frame is then stamped when seen). Seen instants are late by the
polling and the OS, never early, so :class:`CameraFrameClock` puts each frame at its camera time
(frame number over the camera rate) plus the smallest offset between the two clocks over the last
``robot_io.hands.frame_clock.FRAME_CLOCK_WINDOW_S``: the stamps keep the cameras' even spacing.

The SDK: :func:`read_frame` and :func:`resolve` talk to a :class:`ViconClient`, the methods and return
shapes of Vicon's own Python API (``vicon_dssdk.ViconDataStream.Client``: ``GetFrame()`` → bool,
``GetSegmentGlobalTranslation(subject, segment)`` → ((x, y, z), occluded), names as lists). The SDK
installed by the optional extra ``vicon`` is ``pyvicon-datastream``, which :class:`PyViconClient`
adapts; it is imported only when a Vicon source is opened. Frames are read in the SDK's
``ClientPullPreFetch`` mode and polled every :data:`POLL_S`: ``pyvicon-datastream`` holds the GIL in
``get_frame``, and in ``ServerPush`` mode that call blocks until the next frame, which would stall
the control loop for up to a camera period.

A link that heals: a frame that cannot be read (the SDK refused a call about it, or returned no
number) is dropped and counted in the source's link notice, and the next poll reads the next frame.
A connection the SDK reports lost (``GetFrame`` fails: Tracker closed, the network gone) is logged
once; with no new frame for ``robot_io.hands.tracked_hand.LINK_STALL_S`` (the stream lost, or Tracker
paused, which the prefetching SDK shows as the same frame again) the source disconnects and connects
anew, waits for a frame and resolves the names again, trying until the server answers.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from robot_io.errors import HandSourceError
from robot_io.hands.config import ViconSource
from robot_io.hands.frame import FrameTransform
from robot_io.hands.frame_clock import FRAME_CLOCK_WINDOW_S, FrameClock
from robot_io.hands.tracked_hand import RECONNECT_TIMEOUT_S, TrackedHand

log = logging.getLogger(__name__)

#: How to install the SDK's Python bindings (the project's optional extra).
INSTALL = "pip install 'handover-lab[vicon]'"
#: How often the receiver asks the SDK for a new frame [s].
POLL_S = 0.001
#: A reported latency beyond this is not one: the frame is stamped when seen [s].
MAX_REPORTED_LATENCY_S = 0.5


class ViconClient(Protocol):
    """What the source reads of the SDK, as Vicon's own Python API names and shapes it."""

    def GetFrame(self) -> bool: ...  # a frame is there (False: none yet)
    def GetFrameNumber(self) -> int: ...
    def GetFrameRate(self) -> float: ...  # the camera system's rate [Hz]
    def GetLatencyTotal(self) -> float: ...  # [s]; 0.0 when the server reports none
    def GetSubjectNames(self) -> list[str]: ...
    def GetSegmentNames(self, subject: str) -> list[str]: ...
    def GetSegmentGlobalTranslation(self, subject: str,
                                    segment: str) -> tuple[tuple[float, float, float], bool]: ...
    def Disconnect(self) -> None: ...


@dataclass(frozen=True)
class Reading:
    """What one frame of the SDK says of the hand's segment."""

    frame_number: int
    frame_rate_hz: float  # the camera system's rate (0: not known)
    latency_s: float | None  # the SDK's total latency (None: none reported, or none that makes sense)
    position_mm: tuple[float, float, float] | None  # None: lost (occluded, or not in this frame)


def _xyz(values: Iterable[Any]) -> tuple[float, float, float]:
    """The SDK's three coordinates as floats."""
    x, y, z = values
    return float(x), float(y), float(z)


def read_frame(client: ViconClient, subject: str, segment: str) -> Reading:
    """The hand's segment in the client's current frame. A subject or segment this frame does not
    hold exactly once, or that the SDK reports as occluded, is lost (``position_mm`` None)."""
    latency = float(client.GetLatencyTotal())
    position = None
    if (client.GetSubjectNames().count(subject) == 1
            and client.GetSegmentNames(subject).count(segment) == 1):
        translation, occluded = client.GetSegmentGlobalTranslation(subject, segment)
        if not occluded:
            position = _xyz(translation)
    return Reading(int(client.GetFrameNumber()), float(client.GetFrameRate()),
                   latency if 0.0 < latency <= MAX_REPORTED_LATENCY_S else None, position)


def describe_subjects(client: ViconClient) -> str:
    """The subjects of the current frame and their segments, in words."""
    return ", ".join(f"{subject!r} (segments {', '.join(map(repr, client.GetSegmentNames(subject)))})"
                     for subject in client.GetSubjectNames()) or "none"


def resolve(client: ViconClient, subject: str, segment: str, server: str) -> None:
    """Refuse a subject or segment name that the current frame does not hold exactly once, naming
    what it holds."""
    subjects = client.GetSubjectNames()
    if subjects.count(subject) == 1:
        segments = client.GetSegmentNames(subject)
        if segments.count(segment) == 1:
            return
        field, name, count, kind = "vicon_segment", segment, segments.count(segment), "segments"
        where = f"subject {subject!r} on the Vicon DataStream at {server}"
    else:
        field, name, count, kind = "vicon_subject", subject, subjects.count(subject), "subjects"
        where = f"the Vicon DataStream at {server}"
    problem = f"no {kind[:-1]} is" if not count else f"{count} {kind} are"
    raise HandSourceError(f"hand_source.{field} = {name!r}: {problem} named so in {where}; its "
                          f"subjects: {describe_subjects(client)}")


class CameraFrameClock(FrameClock):
    """:class:`FrameClock` for numbered frames at a camera rate (camera time: number / rate). A new
    camera rate starts anew (the cameras were set to another rate); without a rate a frame is
    stamped when seen."""

    def __init__(self, window_s: float = FRAME_CLOCK_WINDOW_S) -> None:
        super().__init__(window_s)
        self._rate: float | None = None

    def stamp_frame(self, frame_number: int, rate_hz: float, seen: float) -> float:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            self.reset()
            self._rate = None
            return seen
        if rate_hz != self._rate:
            self.reset()
        self._rate = rate_hz
        return self.stamp(frame_number / rate_hz, seen)


class PyViconClient:
    """``pyvicon-datastream``'s client with the methods and shapes of :class:`ViconClient`. Its
    ``get_segment_global_translation`` returns None for an occluded segment (and for any failure): a
    lost hand; :func:`read_frame` asks for the names first, so an unknown name never gets there."""

    def __init__(self, sdk, host: str, port: int) -> None:
        self._sdk = sdk
        self._client = sdk.PyViconDatastream()
        self.version = self._client.__version__
        result = self._client.connect(f"{host}:{port}")
        if result != sdk.Result.Success:
            raise HandSourceError(f"no Vicon DataStream server answered at {host}:{port} ({result.name}): "
                                  "is Tracker (or Nexus, Shogun) running, and this PC on its network?")
        try:
            self._check(self._client.enable_segment_data(), "EnableSegmentData")
            self._check(self._client.set_stream_mode(sdk.StreamMode.ClientPullPreFetch), "SetStreamMode")
        except HandSourceError:
            self.Disconnect()
            raise

    def _check(self, result, call: str) -> None:
        if result != self._sdk.Result.Success:
            raise HandSourceError(f"the Vicon DataStream SDK's {call} failed: {result.name}")

    def GetFrame(self) -> bool:
        result = self._client.get_frame()
        if result == self._sdk.Result.NoFrame:
            return False
        self._check(result, "GetFrame")
        return True

    def GetFrameNumber(self) -> int:
        return self._client.get_frame_number()

    def GetFrameRate(self) -> float:
        return self._client.get_frame_rate()

    def GetLatencyTotal(self) -> float:
        return self._client.get_latency_total()

    def GetSubjectNames(self) -> list[str]:
        names = (self._client.get_subject_name(index) for index in range(self._client.get_subject_count()))
        return [name for name in names if name is not None]

    def GetSegmentNames(self, subject: str) -> list[str]:
        count = self._client.get_segment_count(subject) or 0  # None: no such subject
        names = (self._client.get_segment_name(subject, index) for index in range(count))
        return [name for name in names if name is not None]

    def GetSegmentGlobalTranslation(self, subject: str,
                                    segment: str) -> tuple[tuple[float, float, float], bool]:
        translation = self._client.get_segment_global_translation(subject, segment)
        if translation is None:
            return (0.0, 0.0, 0.0), True
        return _xyz(translation), False

    def Disconnect(self) -> None:
        self._client.disconnect()


def connect_sdk(host: str, port: int) -> PyViconClient:
    """The SDK's client, connected to ``host:port``, streaming segments; the SDK is imported here,
    so that the project runs without it when no Vicon source is opened."""
    try:
        import pyvicon_datastream
    except ImportError as exc:
        raise HandSourceError(f'[hand_source] kind = "vicon" needs the Vicon DataStream SDK, which is not '
                              f"installed ({exc}): {INSTALL} "
                              '(docs/hardware.md, "Vicon (DataStream SDK)")') from None
    return PyViconClient(pyvicon_datastream, host, port)


class ViconHand(TrackedHand):
    """Connects, waits for a first frame, resolves the subject and segment by name, then polls the
    SDK for frames on the receiver thread and puts one sample per new frame."""

    PROTOCOL = "Vicon"

    HEALING = "reconnecting"

    def __init__(self, config: ViconSource, transform: FrameTransform, max_speed: float,
                 connect: Callable[[str, int], ViconClient] | None = None) -> None:
        super().__init__(transform, max_speed)
        # ViconSource refuses a table without them (HandSourceBase._tracker_complete)
        assert config.vicon_subject and config.vicon_segment and config.vicon_server is not None
        self.subject, self.segment = config.vicon_subject, config.vicon_segment
        self.server = f"{config.vicon_server}:{config.vicon_port}"
        self._address = (config.vicon_server, config.vicon_port)
        self._connect = connect or connect_sdk
        self.frames = 0
        self.missed = 0  # frames the numbers skipped
        self.first_seen: float | None = None
        self.last_seen: float | None = None
        self.latency_s: float | None = None
        self.camera_rate_hz: float | None = None
        self._last_number: int | None = None
        self._clock = CameraFrameClock()
        self._failing = False
        self.client, seen = self._open(config.resolve_timeout_s)
        try:
            self.take(read_frame(self.client, self.subject, self.segment), seen)
        except BaseException:
            self.client.Disconnect()
            raise
        log.info("Vicon hand source: %s", self.describe())
        self.start()

    def _open(self, timeout: float) -> tuple[ViconClient, float]:
        """A client connected to the server, a frame there and the names resolved in it; the
        instant that frame was seen."""
        client = self._connect(*self._address)
        try:
            seen = self._first_frame(client, timeout)
            resolve(client, self.subject, self.segment, self.server)
        except BaseException:
            client.Disconnect()
            raise
        return client, seen

    def reconnect(self) -> None:
        """Disconnect, then one try to connect anew (waiting at most RECONNECT_TIMEOUT_S for a
        frame); the frame clock starts anew. The last frame number is kept: a paused Tracker
        repeats its frame, which is no new sample (one outage, not one per try)."""
        try:
            self.client.Disconnect()
        except Exception as exc:  # the SDK's own exceptions: a connection already gone
            log.debug("Vicon hand source: disconnecting the lost connection: %s", exc)
        try:
            client, _ = self._open(RECONNECT_TIMEOUT_S)
        except Exception as exc:  # HandSourceError, or the SDK's own: the server is not back yet
            log.debug("Vicon hand source: connecting again failed: %s", exc)
            return
        self.client, self._failing = client, False
        self._clock.reset()

    def _first_frame(self, client: ViconClient, timeout: float) -> float:
        """Wait for a frame; the instant it was seen."""
        deadline = time.monotonic() + timeout
        while not client.GetFrame():
            if time.monotonic() > deadline:
                raise HandSourceError(f"the Vicon DataStream at {self.server} sent no frame within "
                                      f"resolve_timeout_s = {timeout} s (is it live, not paused?)")
            time.sleep(POLL_S)
        return time.monotonic()

    def receive_once(self) -> None:
        """One poll: the current frame's sample if its number is new (the rest of a frame is read
        only then: most polls find the frame they found before)."""
        try:
            fresh = self.client.GetFrame()
        except Exception:
            if not self._failing:
                log.exception("Vicon hand source: reading a frame failed (logged once until one is read)")
            self._failing = True
            time.sleep(0.1)
            return
        self._failing = False
        seen = time.monotonic()
        if fresh:
            self._read(seen)
        time.sleep(POLL_S)

    def _read(self, seen: float) -> None:
        """The current frame's sample if its number is new; a frame that cannot be read is
        dropped and counted, once if its number could be read (else at each poll until it can)."""
        number = None
        try:
            number = int(self.client.GetFrameNumber())
            if number == self._last_number:
                return
            reading = read_frame(self.client, self.subject, self.segment)
        except Exception as exc:  # the SDK's own exceptions, or a value that is no number
            self.link.dropped(f"{type(exc).__name__}: {exc}")
            self._last_number = number if number is not None else self._last_number
            return
        self.take(reading, seen)

    def take(self, reading: Reading, seen: float) -> None:
        """One sample from a new frame first seen at ``seen`` (``time.monotonic``)."""
        last, number = self._last_number, reading.frame_number
        if last is not None and number > last + 1:
            self.missed += number - last - 1
        self._last_number = number
        measured = self._clock.stamp_frame(number, reading.frame_rate_hz, seen - (reading.latency_s or 0.0))
        lost = reading.position_mm is None
        self.put(measured, np.full(3, np.nan) if lost else reading.position_mm)
        self.frames += 1
        self.latency_s, self.camera_rate_hz = reading.latency_s, reading.frame_rate_hz or None
        self.last_seen = seen
        self.first_seen = self.first_seen or seen

    def rate_hz(self) -> float | None:
        """New frames per second over those received (None before two)."""
        first, last = self.first_seen, self.last_seen
        if self.frames < 2 or first is None or last is None or last == first:
            return None
        return (self.frames - 1) / (last - first)

    def describe(self) -> str:
        """Which segment of which subject from which server, in words."""
        version = getattr(self.client, "version", None)
        sdk = f" (DataStream SDK {version})" if version else ""
        return f"subject {self.subject!r}, segment {self.segment!r} from {self.server}{sdk}"

    def detail(self) -> str:
        """:meth:`describe`, the stream's rate, the cameras' and the latency the SDK reports."""
        rate = self.rate_hz()
        parts = [self.describe(), "no rate yet" if rate is None else f"{rate:.0f} Hz"]
        if self.camera_rate_hz:
            parts.append(f"cameras at {self.camera_rate_hz:g} Hz")
        parts.append("latency not reported (stamped when seen)" if self.latency_s is None
                     else f"latency {1e3 * self.latency_s:.1f} ms")
        if self.missed:
            parts.append(f"{self.missed} frames missed")
        return ", ".join(parts)

    def _release(self) -> None:
        """Disconnect (once polling has stopped)."""
        try:
            self.client.Disconnect()
        except Exception:
            log.exception("Vicon hand source: disconnecting failed")
