"""A hand source reading OptiTrack Motive's NatNet stream with the ``natnet`` client (unicast).

Which rigid body: the one named ``[hand_source] natnet_rigid_body`` in the server's model
definitions, never "the first one streamed"; a name no rigid body has, or that more than one has, is
refused with the list of those that exist.

Samples: each frame's rigid body of that id, in metres (NatNet's unit; ``units_to_m`` is 1.0), put
through the tracker → robot-base transform. A rigid body the frame marks as not tracked (its
tracking-valid flag off; Motive then sends zeros or its last pose) or leaves out is a lost hand: a
NaN sample, never a position.

Time stamps: the frame's own time stamp (seconds since Motive started, from the camera's frame
counter) carried onto ``time.monotonic`` by :class:`robot_io.hands.frame_clock.FrameClock`, from the
frames' arrival minus the latency each reports: frames that arrive late together keep their own
spacing. NatNet 3.0 and later carry that latency as host-clock ticks — the camera's mid-exposure (0
where the cameras cannot measure it: then the data's arrival at the host) and the transmission —
and the ``natnet`` client does not report the tick rate (``NAT_SERVERINFO``'s
``HighResClockFrequency``); the rate is therefore learned from the stream: ticks of mid-exposure
over the frames' own time stamp across at least :data:`RATE_BASELINE_S`. Until then, and for older
protocols, the arrival alone counts.

A link that heals: the ``natnet`` client reads each packet on its own receiving thread, which any
exception ends for good (a truncated frame raises ``struct.error``; every later frame arrives and is
never read). :class:`TolerantNatNetClient` drops a packet it cannot read and counts it in
:attr:`TrackedHand.link`. Whatever else stops the frames — a receiving thread that ended anyway,
Motive closed, restarted or its PC gone from the network — a watchdog thread notices: nothing
received for ``robot_io.hands.tracked_hand.LINK_STALL_S`` is a lost link, and the client is made anew
(connect, model definitions, the rigid body resolved by name again: Motive may number it
differently after a restart) until one streams again; each try waits at most
``RECONNECT_TIMEOUT_S``. Motive restarted forgets its unicast clients, so only a new connection is
streamed to again.
"""

from __future__ import annotations

import logging
import socket
import struct
import threading
import time
from collections.abc import Callable

import numpy as np
from natnet import DataDescriptions, DataFrame, NatNetClient
from natnet.packet_buffer import PacketBuffer

from robot_io.errors import HandSourceError
from robot_io.hands.config import NatNetSource
from robot_io.hands.frame import FrameTransform
from robot_io.hands.frame_clock import FrameClock
from robot_io.hands.tracked_hand import RECEIVER_JOIN_S, RECONNECT_TIMEOUT_S, TrackedHand

log = logging.getLogger(__name__)

#: The frames' time span over which the host clock's tick rate is learned [s].
RATE_BASELINE_S = 0.5
#: A reported latency beyond this is not one (a tick rate learned across a restart of Motive's
#: clock or a change of its camera rate): the frame is stamped on arrival and the rate learned anew [s].
MAX_REPORTED_LATENCY_S = 0.5
#: How often the model definitions are asked for again while none have come [s] (UDP may drop one).
MODELDEF_RETRY_S = 0.5
#: How often the watchdog looks at the link [s].
WATCH_S = 0.05


def local_address_for(server: str, port: int) -> str:
    """The address this machine uses to reach ``server``: a UDP socket's connect picks the route
    (nothing is sent) and getsockname names its source address."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect((server, port))
        return probe.getsockname()[0]


class TickRate:
    """The host clock's ticks per second, learned from (frame time stamp [s], host ticks) pairs:
    the slope between the first pair and one at least ``baseline_s`` later."""

    def __init__(self, baseline_s: float = RATE_BASELINE_S) -> None:
        self.baseline_s = baseline_s
        self._first: tuple[float, int] | None = None
        self.hz: float | None = None

    def add(self, timestamp: float, ticks: int) -> None:
        if self._first is None or timestamp < self._first[0] or ticks < self._first[1]:
            self._first, self.hz = (timestamp, ticks), None  # a new stream (Motive restarted)
            return
        span = timestamp - self._first[0]
        if span >= self.baseline_s:
            self.hz = (ticks - self._first[1]) / span

    def reset(self) -> None:
        """Learn the rate anew from the next pair on."""
        self._first, self.hz = None, None


def reported_latency(frame: DataFrame, rate: TickRate) -> float | None:
    """The camera-to-transmit latency ``frame`` reports [s]: (transmit − mid-exposure) ticks over
    the learned tick rate; None where it reports none (protocol before 3.0), the tick rate is not
    known yet, or the result is no latency (negative or above :data:`MAX_REPORTED_LATENCY_S`: the
    rate is then learned anew)."""
    suffix = frame.suffix
    if suffix.stamp_transmit is None:
        return None
    measured = suffix.stamp_camera_mid_exposure or suffix.stamp_data_received
    if not measured:
        return None
    rate.add(suffix.timestamp, measured)
    if not rate.hz or rate.hz <= 0:
        return None
    latency = (suffix.stamp_transmit - measured) / rate.hz
    if not 0.0 <= latency <= MAX_REPORTED_LATENCY_S:
        rate.reset()
        return None
    return latency


def describe_bodies(descriptions: DataDescriptions) -> str:
    return ", ".join(f"{body.name!r} (id {body.id_num})" for body in descriptions.rigid_bodies) or "none"


#: The first two bytes of a ``NAT_SERVERINFO`` packet (its message id, little endian).
SERVER_INFO_ID = struct.pack("<H", NatNetClient.NAT_SERVERINFO)


class TolerantNatNetClient(NatNetClient):
    """The ``natnet`` client (0.3), whose receiving threads survive a packet they cannot read.

    The library reads each packet in its private ``NatNetClient.__process_message``, on a receiving
    thread that an exception ends. This subclass overrides that one method (by its mangled name):
    a packet that cannot be read (``struct.error`` of a truncated one, a bad string, an index past
    its end) is dropped and reported to ``on_malformed``, one shorter than its header says before
    the library prints a warning on stdout for it (one line per bad frame in the experimenter's
    terminal; counted here, and logged once by the link), and one longer is read as far as its
    header says; and a packet that comes before the server's info is dropped uncounted: the library
    cannot read it without the protocol's version (it raised TypeError out of ``connect`` when a
    frame overtook the info). Everything else is the library's. Should a later ``natnet`` rename
    the method, the override goes unused and the watchdog of :class:`NatNetHand` still makes the
    client anew after a dead thread."""

    def __init__(self, on_malformed: Callable[[str], None], **kwargs) -> None:
        super().__init__(**kwargs)
        self._on_malformed = on_malformed

    def _NatNetClient__process_message(self, buffer) -> None:  # noqa: N802 (the library's name)
        try:
            if self.protocol_version is None and buffer.data[:2] != SERVER_INFO_ID:
                return
            data = buffer.data
            announced = 4 + struct.unpack_from("<H", data, 2)[0] if len(data) >= 4 else None
            if announced is None or len(data) < announced:
                # the library would print a warning on stdout for it, then fail to read it
                self._on_malformed(f"a packet of {len(data)} bytes, its header says {announced}")
                return
            if len(data) > announced:  # trailing bytes: read what the header announces
                buffer = PacketBuffer(data[:announced])
            super()._NatNetClient__process_message(buffer)
        except (struct.error, ValueError, IndexError) as exc:
            self._on_malformed(f"{type(exc).__name__}: {exc}")


class NatNetHand(TrackedHand):
    """Connects to Motive, resolves the rigid body's name to its id, then puts every frame's sample
    from the client's receiving thread; a watchdog thread connects again when the frames stop."""

    PROTOCOL = "NatNet"

    HEALING = "reconnecting"

    def __init__(self, config: NatNetSource, transform: FrameTransform, max_speed: float) -> None:
        super().__init__(transform, max_speed)
        # NatNetSource refuses a table without them (HandSourceBase._tracker_complete)
        assert config.natnet_rigid_body and config.natnet_server is not None
        self.rigid_body = config.natnet_rigid_body
        self.server = (config.natnet_server, config.natnet_command_port)
        self._local = config.natnet_local_address or local_address_for(*self.server)
        self.body_id: int | None = None
        self.frames = 0
        self.first_arrival: float | None = None
        self.last_arrival: float | None = None
        self.latency_s: float | None = None
        self._rate = TickRate()
        self._clock = FrameClock()
        self.client = self._open(config.resolve_timeout_s, "resolve_timeout_s = ")
        info = self.client.server_info
        self.server_detail = f"{info.application_name} (NatNet {self.client.protocol_version})"
        log.info("NatNet hand source: rigid body %r (id %d) from %s at %s:%d", self.rigid_body,
                 self.body_id, self.server_detail, *self.server)
        self._closing = threading.Event()
        self._watchdog = threading.Thread(target=self._watch, name="natnet-watchdog", daemon=True)
        self._watchdog.start()

    def _open(self, timeout: float, within: str) -> NatNetClient:
        """A client connected to the server, its rigid body's id resolved, its threads receiving
        (``within`` names where the timeout comes from, for the refusals)."""
        client = TolerantNatNetClient(self.link.dropped, server_ip_address=self.server[0],
                                      local_ip_address=self._local, command_port=self.server[1],
                                      use_multicast=False)
        descriptions: list[DataDescriptions] = []
        described = threading.Event()

        def on_descriptions(received: DataDescriptions) -> None:
            if not described.is_set():
                descriptions.append(received)
                described.set()

        client.on_data_description_received_event.handlers.append(on_descriptions)
        client.on_data_frame_received_event.handlers.append(self._on_frame)
        try:
            self._connect(client, descriptions, described, timeout, within)
        except BaseException:
            client.shutdown()
            raise
        return client

    def _connect(self, client: NatNetClient, descriptions: list[DataDescriptions],
                 described: threading.Event, timeout: float, within: str) -> None:
        try:
            client.connect(timeout=timeout)
        except OSError as exc:  # TimeoutError: nothing answered; others: the network refused
            said = "" if isinstance(exc, TimeoutError) else f" ({exc})"
            raise HandSourceError(f"no NatNet server answered at {self.server[0]}:{self.server[1]} "
                                  f"within {within}{timeout} s{said} (is Motive streaming, "
                                  "in unicast, to this machine's network?)") from None
        client.run_async()
        deadline = time.monotonic() + timeout
        while not described.is_set():
            client.request_modeldef()
            if time.monotonic() > deadline:
                raise HandSourceError(f"the NatNet server at {self.server[0]}:{self.server[1]} sent no "
                                      f"model definitions within {within}{timeout} s")
            described.wait(MODELDEF_RETRY_S)
        ids = [body.id_num for body in descriptions[0].rigid_bodies if body.name == self.rigid_body]
        if len(ids) != 1:
            problem = "no rigid body is" if not ids else f"{len(ids)} rigid bodies are"
            raise HandSourceError(f"hand_source.natnet_rigid_body = {self.rigid_body!r}: {problem} "
                                  f"named so on the NatNet server at {self.server[0]}:{self.server[1]}; "
                                  f"its rigid bodies: {describe_bodies(descriptions[0])}")
        self.body_id = ids[0]

    def _watch(self) -> None:
        """The watchdog's thread: the link watch of every tracked hand (TrackedHand._watch_link),
        which the client's own receiving thread cannot do (it may be the one that ended)."""
        while not self._closing.wait(WATCH_S):
            self._watch_link()

    def reconnect(self) -> None:
        """Make the client anew: one try, waiting at most RECONNECT_TIMEOUT_S."""
        self.body_id = None  # frames of the old client, if any still come, are not the hand's
        self.client.shutdown()
        try:
            self.client = self._open(RECONNECT_TIMEOUT_S, "")
        except HandSourceError as exc:
            log.debug("NatNet hand source: connecting again failed: %s", exc)

    def _on_frame(self, frame: DataFrame) -> None:
        """The client's thread: one sample per frame once the rigid body is known (an exception
        here would end the client's thread: it is logged instead)."""
        arrived = time.monotonic()
        try:
            if self.body_id is None:
                return
            if not self.link.up:  # a new connection (put says the link is back): Motive's clock
                self._rate.reset()  # may have started anew
                self._clock.reset()
            latency = reported_latency(frame, self._rate)
            body = next((b for b in frame.rigid_bodies if b.id_num == self.body_id), None)
            stamp = self._clock.stamp(frame.suffix.timestamp, arrived - (latency or 0.0))
            tracked = body is not None and body.tracking_valid is not False
            self.put(stamp, body.pos if tracked and body is not None else np.full(3, np.nan))
            self.frames += 1
            self.latency_s, self.last_arrival = latency, arrived
            self.first_arrival = self.first_arrival or arrived
        except Exception:
            log.exception("NatNet hand source: a frame could not be read")

    def rate_hz(self) -> float | None:
        """Frames per second over those received (None before two)."""
        first, last = self.first_arrival, self.last_arrival
        if self.frames < 2 or first is None or last is None or last == first:
            return None
        return (self.frames - 1) / (last - first)

    def describe(self) -> str:
        """Which rigid body of which server, in words."""
        return (f"rigid body {self.rigid_body!r} (id {self.body_id}) from {self.server_detail} at "
                f"{self.server[0]}:{self.server[1]}")

    def detail(self) -> str:
        """:meth:`describe`, the stream's rate and the latency it reports, in words."""
        rate = self.rate_hz()
        latency = ("latency not reported (stamped on arrival)" if self.latency_s is None
                   else f"latency {1e3 * self.latency_s:.1f} ms")
        return (f"{self.describe()}, " + ("no rate yet" if rate is None else f"{rate:.0f} Hz")
                + f", {latency}")

    def close(self) -> None:
        """Stop the watchdog, then the client's threads, and close its sockets."""
        self._closing.set()
        self._watchdog.join(RECEIVER_JOIN_S)
        self.client.shutdown()
        super().close()
