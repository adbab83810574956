"""A stand-in OptiTrack Motive: a UDP server that speaks NatNet 3.1, 4.0 or 4.1 (unicast) to a real
NatNet client. Motive 2.x streams 3.1, Motive 3.0 streams 4.0 and Motive 3.1 and later 4.1
(:data:`MOTIVE_OF`).

It answers ``NAT_CONNECT`` with ``NAT_SERVERINFO`` (application "Motive" of the version that streams
that protocol, the host's high-resolution clock at :data:`CLOCK_HZ` ticks per second),
``NAT_REQUEST_MODELDEF`` with ``NAT_MODELDEF`` listing its rigid bodies (name, id), and streams
``NAT_FRAMEOFDATA`` at ``rate_hz`` to every client that connected, as Motive streams in unicast.
Each frame carries, per rigid body, its position [m], orientation (quaternion x, y, z, w), mean
marker error [m] and the tracking-valid flag (bit 0 of its parameters), and the frame's time stamps:
the camera's mid-exposure, the data's arrival at the host and the transmission, in ticks of the host
clock (here ``time.monotonic``).

The packets are packed with :mod:`struct` field by field as OptiTrack's own Python client
(``natnetsdk`` 4.1, ``NatNetClient.py``) and the ``natnet`` package (0.3.0) unpack them: little
endian, strings NUL-terminated, the server's name in a fixed 256 bytes. What 4.x adds: from 4.0 a
frame's suffix carries the precision time stamp (whole seconds and fraction, two uint32) before its
parameters; from 4.1 each list of a frame (marker sets, other markers, rigid bodies, skeletons, the
new assets, labelled markers, force plates, devices) and each model description is preceded by its
size in bytes after its count or type. It is a test and rehearsal stand-in for Motive, not a mock:
the client talks to it over real UDP sockets.

Faults, for the tests of a link that heals: :meth:`NatNetStandin.send_truncated_frame` cuts the next
frame short (a packet damaged on its way; its header still gives the whole length), and a stand-in
closed and started anew on the same port is Motive restarted: it has forgotten its clients, which
must connect again to be streamed to.
"""

from __future__ import annotations

import logging
import math
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import NamedTuple

log = logging.getLogger(__name__)

NAT_CONNECT, NAT_SERVERINFO, NAT_REQUEST_MODELDEF, NAT_MODELDEF, NAT_FRAMEOFDATA = 0, 1, 4, 5, 7
#: The NatNet protocol (major, minor) the stand-in speaks unless told otherwise.
PROTOCOL_VERSION = (3, 1)
#: The Motive version that streams each protocol the stand-in speaks (its NAT_SERVERINFO says so).
MOTIVE_OF = {(3, 1): (2, 3, 7, 0), (4, 0): (3, 0, 3, 0), (4, 1): (3, 1, 0, 0)}
#: The host's high-resolution clock [ticks/s] (a Windows performance counter runs at 10 MHz).
CLOCK_HZ = 10_000_000
#: NatNet's data-description type of a rigid body.
RIGID_BODY_DESCRIPTION = 1


class RigidBodySpec(NamedTuple):
    """A rigid body the stand-in describes: its name in Motive and its streaming id."""

    name: str
    id: int


class RigidBodyPose(NamedTuple):
    """One rigid body in one frame; ``tracked=False`` is Motive's tracking-valid flag off."""

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    mean_error: float = 0.0
    tracked: bool = True


class Snapshot(NamedTuple):
    """Rigid-body poses with the instant they were measured (``time.monotonic``)."""

    poses: Mapping[int, RigidBodyPose]
    measured_at: float


#: Where the stand-in's rigid bodies are, called once per frame: id → pose (an id left out is not in
#: the frame), measured ``latency_s`` before the frame is sent; or a :class:`Snapshot` that says when
#: they were measured (a hand played elsewhere at its own pace: the frame's exposure is that instant,
#: so its position and its time stamp agree however the two paces beat).
Poses = Callable[[], Mapping[int, RigidBodyPose] | Snapshot]


def _packet(message: int, payload: bytes) -> bytes:
    return struct.pack("<HH", message, len(payload)) + payload


def _sized(protocol: tuple[int, int], head: bytes, body: bytes) -> bytes:
    """``head`` (a count or a type), from 4.1 the size of ``body`` in bytes, then ``body``."""
    return head + (struct.pack("<I", len(body)) if protocol >= (4, 1) else b"") + body


def _empty_list(protocol: tuple[int, int]) -> bytes:
    """A frame's list with no element: its count 0 (and from 4.1 its size 0)."""
    return _sized(protocol, struct.pack("<I", 0), b"")


def _string(text: str) -> bytes:
    return text.encode() + b"\0"


def server_info(protocol: tuple[int, int] = PROTOCOL_VERSION, application: str = "Motive",
                data_port: int = 1511) -> bytes:
    """``NAT_SERVERINFO``: the sender (name in 256 bytes, its version, the NatNet version), then
    the host clock's frequency, the data port, unicast and no multicast group (``sSender_Server``;
    the client reads the sender)."""
    sender = struct.pack("<256s4B4B", application.encode(), *MOTIVE_OF[protocol], *protocol, 0, 0)
    return _packet(NAT_SERVERINFO, sender + struct.pack("<QH?4B", CLOCK_HZ, data_port, False, 0, 0, 0, 0))


def model_definitions(rigid_bodies: Sequence[RigidBodySpec],
                      protocol: tuple[int, int] = PROTOCOL_VERSION) -> bytes:
    """``NAT_MODELDEF`` with one rigid-body description per body: name, id, no parent (-1 as
    unsigned), zero offset, no markers (3.x and 4.x describe markers here; the hand needs none)."""
    payload = struct.pack("<I", len(rigid_bodies))
    for body in rigid_bodies:
        payload += _sized(protocol, struct.pack("<I", RIGID_BODY_DESCRIPTION), _string(body.name)
                          + struct.pack("<II3fI", body.id, 0xFFFFFFFF, 0.0, 0.0, 0.0, 0))
    return _packet(NAT_MODELDEF, payload)


class FrameStamps(NamedTuple):
    """A frame's times on the host clock [s]: mid-exposure, data received, transmitted."""

    exposure: float
    received: float
    transmit: float


def frame_of_data(frame: int, poses: Mapping[int, RigidBodyPose], timestamp: float,
                  stamps: FrameStamps, protocol: tuple[int, int] = PROTOCOL_VERSION) -> bytes:
    """``NAT_FRAMEOFDATA``: frame number, no marker sets or other markers, the rigid bodies, no
    skeletons, (4.1: assets,) labelled markers, force plates or devices, then the suffix: timecode,
    the frame's time stamp [s] (double), the three host-clock stamps [ticks], (4.x: the precision
    time stamp, whole seconds and fraction of 2³²,) and its parameters."""
    bodies = b"".join(struct.pack("<I3f4ffH", body_id, *pose.position, *pose.orientation,
                                  pose.mean_error, 1 if pose.tracked else 0)
                      for body_id, pose in poses.items())
    lists_after_bodies = 4 if protocol < (4, 1) else 5  # skeletons, (assets,) labelled, plates, devices
    payload = (struct.pack("<I", frame) + _empty_list(protocol) + _empty_list(protocol)
               + _sized(protocol, struct.pack("<I", len(poses)), bodies)
               + _empty_list(protocol) * lists_after_bodies)
    ticks = [round(t * CLOCK_HZ) for t in stamps]
    payload += struct.pack("<IId3Q", 0, 0, timestamp, *ticks)
    if protocol >= (4, 0):
        seconds = math.floor(timestamp)
        payload += struct.pack("<II", seconds, round((timestamp - seconds) * 2**32) % 2**32)
    payload += struct.pack("<H", 0)
    return _packet(NAT_FRAMEOFDATA, payload)


class NatNetStandin:
    """The server: bound on ``host``:``port`` (0: a free port, see :attr:`address`), it answers
    requests at once and streams frames at ``rate_hz`` from :meth:`start` until :meth:`close`.
    ``latency_s`` is the camera-to-transmit latency each frame reports for poses given without
    their instant (they are taken as measured that long before the frame is sent)."""

    def __init__(self, rigid_bodies: Sequence[RigidBodySpec], poses: Poses, host: str = "127.0.0.1",
                 port: int = 0, rate_hz: float = 120.0, latency_s: float = 0.004,
                 protocol: tuple[int, int] = PROTOCOL_VERSION) -> None:
        if protocol not in MOTIVE_OF:
            raise ValueError(f"NatNet stand-in: protocol = {protocol}: must be one of "
                             + ", ".join(f"{major}.{minor}" for major, minor in MOTIVE_OF))
        self.protocol = protocol
        self.rigid_bodies, self.poses = list(rigid_bodies), poses
        self.rate_hz, self.latency_s = rate_hz, latency_s
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.settimeout(0.1)
        self.address: tuple[str, int] = self.sock.getsockname()
        self.clients: list[tuple[str, int]] = []
        self.frames_sent = 0
        self.truncated_sent = 0  # frames sent cut short (send_truncated_frame)
        self._truncate = threading.Event()
        self._lock = threading.Lock()
        self._running = False
        self._threads: list[threading.Thread] = []

    def start(self) -> NatNetStandin:
        self._running = True
        self._started = time.monotonic()
        for target, name in ((self._answer, "natnet-commands"), (self._stream, "natnet-frames")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def _answer(self) -> None:
        while self._running:
            try:
                data, client = self.sock.recvfrom(65536)
            except (TimeoutError, OSError):
                continue
            if len(data) < 4:
                continue
            message = struct.unpack_from("<H", data)[0]
            if message == NAT_CONNECT:
                with self._lock:
                    if client not in self.clients:
                        self.clients.append(client)
                self._send(server_info(self.protocol), client)
            elif message == NAT_REQUEST_MODELDEF:
                self._send(model_definitions(self.rigid_bodies, self.protocol), client)
            # keep-alives and commands need no answer from a stand-in

    def _stream(self) -> None:
        next_at = time.monotonic()
        while self._running:
            now = time.monotonic()
            with self._lock:
                clients = list(self.clients)
            if clients:
                taken = self.poses()
                poses, exposure = ((taken.poses, min(taken.measured_at, now))
                                   if isinstance(taken, Snapshot) else (taken, now - self.latency_s))
                packet = frame_of_data(self.frames_sent, poses, exposure - self._started,
                                       FrameStamps(exposure, (exposure + now) / 2, now), self.protocol)
                if self._truncate.is_set():
                    packet = packet[:len(packet) // 2]
                    self._truncate.clear()
                    self.truncated_sent += 1
                for client in clients:
                    self._send(packet, client)
                self.frames_sent += 1
            next_at = max(next_at + 1.0 / self.rate_hz, now)
            # pacing, not waiting for a state: a tracker streams at its own rate
            time.sleep(max(0.0, next_at - time.monotonic()))

    def send_truncated_frame(self) -> None:
        """Cut the next frame to half its length (its header still says the whole length)."""
        self._truncate.set()

    def _send(self, packet: bytes, client: tuple[str, int]) -> None:
        try:
            self.sock.sendto(packet, client)
        except OSError as exc:  # a client that went away: Motive streams on regardless
            log.debug("NatNet stand-in: sending to %s failed: %s", client, exc)

    def close(self) -> None:
        """Stop answering and streaming, and release the port."""
        self._running = False
        for thread in self._threads:
            thread.join(1.0)
        self.sock.close()


def hidden() -> RigidBodyPose:
    """A rigid body Motive has lost: tracking-valid off (Motive sends zeros for it)."""
    return RigidBodyPose((0.0, 0.0, 0.0), tracked=False)


def pose_at(position: Iterable[float]) -> RigidBodyPose:
    """A tracked pose at ``position`` [m], or :func:`hidden` if it has no finite position."""
    x, y, z = (float(v) for v in position)
    return RigidBodyPose((x, y, z)) if all(math.isfinite(v) for v in (x, y, z)) else hidden()
