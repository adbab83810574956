"""A hand source reading a Lab Streaming Layer stream (Vicon, OptiTrack and most mocap systems publish
one). The stream's channels ``lsl_channels`` hold the marker's x, y, z in tracker units.

Which stream: exactly one stream on the network may satisfy ``[hand_source]``'s type (and name, when
set); the source never follows "the first one that answered". A resolve returns as soon as *one*
stream answers, so with a second stream of the type on the network (another rehearsal, another
suite's Mocap stream, a second tracker bridge) the answer could be either: the name is therefore part
of the resolve's predicate, and after the first answer the network gets :data:`DISCOVERY_WINDOW_S`
to show a second match, which is refused with the list of what answered.

A stream that goes away and comes back: LSL's inlet recovers a stream that has a ``source_id`` by
itself (it resolves it anew in the background, a second or two); meanwhile nothing arrives, which the
source's link notice shows as lost, then back. A stream without one cannot be recovered by LSL: every
pull raises ``LostError``. The source then resolves the stream anew (the same predicate, refusing two
as at open) and opens an inlet on it, trying again until it answers; the samples in between are lost.
"""

from __future__ import annotations

import logging
import time

import pylsl
from pylsl.util import LostError
from pylsl.util import TimeoutError as LSLTimeoutError

from robot_io.errors import HandSourceError
from robot_io.hands.config import LSLSource
from robot_io.hands.frame import FrameTransform
from robot_io.hands.tracked_hand import RECONNECT_TIMEOUT_S, TrackedHand

log = logging.getLogger(__name__)

#: After the first matching stream answered, how long a second one gets to answer [s]. Outlets answer
#: a resolve's query within milliseconds on a LAN (on loopback under load, tens of ms); the resolve
#: returns at once when a second one answers, so one stream costs this window once, at open.
DISCOVERY_WINDOW_S = 1.0


def xpath_literal(value: str) -> str:
    """``value`` as an XPath 1.0 string literal (XPath has no escapes: a value holding both quote
    kinds is spelled with ``concat``)."""
    if "'" not in value:
        return f"'{value}'"
    if '"' not in value:
        return f'"{value}"'
    parts = value.split("'")
    return "concat(" + ", \"'\", ".join(f"'{part}'" for part in parts) + ")"


def stream_predicate(config: LSLSource) -> str:
    """The XPath predicate a stream's description must satisfy: its type, and its name when set."""
    predicate = f"type={xpath_literal(config.lsl_stream_type)}"
    if config.lsl_stream_name is not None:
        predicate = f"name={xpath_literal(config.lsl_stream_name)} and {predicate}"
    return predicate


def describe_stream(info: pylsl.StreamInfo) -> str:
    return (f"{info.name()!r} (source_id {info.source_id()!r}, host {info.hostname()!r}, "
            f"{info.channel_count()} channels)")


def resolve_one(config: LSLSource, window: float = DISCOVERY_WINDOW_S) -> pylsl.StreamInfo:
    """The one stream that satisfies ``config``'s type (and name); a :class:`HandSourceError` if none
    answers within ``resolve_timeout_s`` or more than one answers within ``window`` of the first."""
    predicate = stream_predicate(config)
    wanted = (f"LSL stream of type {config.lsl_stream_type!r}"
              + (f" named {config.lsl_stream_name!r}" if config.lsl_stream_name is not None else ""))
    first = pylsl.resolve_bypred(predicate, 1, config.resolve_timeout_s)
    if not first:
        raise HandSourceError(f"no {wanted} found within resolve_timeout_s = "
                              f"{config.resolve_timeout_s} s")
    # a second resolve waits until two answer (at once when a second exists) or the window ends
    found = {info.uid(): info for info in [*first, *pylsl.resolve_bypred(predicate, 2, window)]}
    if len(found) > 1:
        listed = "; ".join(describe_stream(info) for info in found.values())
        fix = ("set hand_source.lsl_stream_name to the one to use" if config.lsl_stream_name is None
               else "stop the other or give each tracker stream a name of its own")
        raise HandSourceError(f"{len(found)} streams answered as the {wanted}: {listed}; {fix}")
    return first[0]


class LSLHand(TrackedHand):
    """Resolves the one stream of the type (and name), then pulls samples in a thread."""

    HEALING = "reconnecting"
    PROTOCOL = "LSL"

    def __init__(self, config: LSLSource, transform: FrameTransform, max_speed: float) -> None:
        super().__init__(transform, max_speed)
        self.config = config
        self.channels = list(config.lsl_channels)
        self.inlet = self._open(config)
        self._lost = False  # the inlet raised LostError: a stream LSL cannot recover
        self.start()

    def _open(self, config: LSLSource) -> pylsl.StreamInlet:
        """An inlet on the one stream ``config`` names, open (waiting at most resolve_timeout_s)."""
        info = resolve_one(config)
        if max(self.channels) >= info.channel_count():
            raise HandSourceError(f"hand_source.lsl_channels = {tuple(self.channels)} but stream "
                                  f"{info.name()!r} has {info.channel_count()} channels")
        self.name, self.nominal_rate_hz = info.name(), info.nominal_srate()
        self.source_id, self.hostname = info.source_id(), info.hostname()
        inlet = pylsl.StreamInlet(info, max_buflen=1, processing_flags=pylsl.proc_clocksync)
        inlet.open_stream(timeout=config.resolve_timeout_s)
        log.info("LSL hand source: stream %s at %g Hz", describe_stream(info), self.nominal_rate_hz)
        return inlet

    def describe(self) -> str:
        """The stream by its name and type."""
        return f"stream {self.name!r} ({self.config.lsl_stream_type})"

    def reconnect(self) -> None:
        """A stream LSL cannot recover (no source_id) is resolved anew; one with a source_id LSL
        recovers by itself, and its inlet stays."""
        if not self._lost:
            return
        try:
            inlet = self._open(self.config.model_copy(update={"resolve_timeout_s": RECONNECT_TIMEOUT_S}))
        except (HandSourceError, LSLTimeoutError, LostError) as exc:
            log.debug("LSL hand source: the stream is not back yet: %s", exc)
            return
        lost, self.inlet, self._lost = self.inlet, inlet, False
        lost.close_stream()

    def receive_once(self) -> None:
        if self._lost:  # the receiver's link watch calls reconnect
            time.sleep(0.1)
            return
        try:
            self._pull()
        except LostError:
            self._lost = True
            self.link.lost(f"stream {self.name!r} lost; it has no source_id, which LSL needs to "
                           "recover it itself", since=self._arrived_at)

    def _pull(self) -> None:
        # Wait for one sample (pull_chunk waits out its whole timeout, which would age every
        # sample), then take whatever else has queued without waiting: a backlog (the stream's first
        # ~0.6 s arrive at once while clock sync starts, or a network stall) is put in one wake.
        # One sample per wake drained it at one sample per GIL turn (~2 ms) while the control loop
        # ran, so the newest sample stayed hundreds of ms old and a trial could end tracker_lost.
        # proc_clocksync maps the outlet's time stamps onto pylsl.local_clock(), which on Linux is
        # the monotonic clock that time.monotonic() reads.
        sample, stamp = self.inlet.pull_sample(timeout=0.1)
        if sample is None:
            return
        samples, stamps = self.inlet.pull_chunk(timeout=0.0)
        for queued, queued_stamp in zip([sample, *samples], [stamp, *stamps], strict=True):
            self.put(queued_stamp, [queued[c] for c in self.channels])

    def _release(self) -> None:
        self.inlet.close_stream()
