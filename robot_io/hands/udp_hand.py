"""A hand source for anything that can send UDP: one JSON object per datagram,
``{"x": …, "y": …, "z": …}`` in tracker units, optionally ``"t"``: the measurement time on this
machine's ``time.monotonic`` clock (otherwise the arrival time is used). ``null`` coordinates mark
an occluded marker.

A datagram that is not such an object (not JSON, not UTF-8, nested past the parser's depth, a
coordinate that is no number) is dropped and counted in the source's link notice; the receiver goes
on with the next at once. UDP has no connection: a sender that stops and starts again is simply read
again (nothing for 0.5 s shows as a lost link until then)."""

from __future__ import annotations

import json
import logging
import socket
import time

from robot_io.hands.config import UDPSource
from robot_io.hands.frame import FrameTransform
from robot_io.hands.tracked_hand import TrackedHand

log = logging.getLogger(__name__)


class UDPHand(TrackedHand):
    """JSON datagrams of the hand marker, on the address it listens on."""

    PROTOCOL = "UDP"

    def __init__(self, config: UDPSource, transform: FrameTransform, max_speed: float) -> None:
        super().__init__(transform, max_speed)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((config.udp_host, config.udp_port))
        self.sock.settimeout(0.1)
        self.address = self.sock.getsockname()
        log.info("UDP hand source on %s:%d", *self.address)
        self.start()

    def describe(self) -> str:
        """The address it listens on."""
        return "on {}:{}".format(*self.address)

    def receive_once(self) -> None:
        try:
            data = self.sock.recv(65536)
        except TimeoutError:
            return
        arrived = time.monotonic()
        try:
            message = json.loads(data)
            xyz = [float("nan") if message[k] is None else float(message[k]) for k in "xyz"]
            stamp = float(message.get("t", arrived))
        except (ValueError, KeyError, TypeError, RecursionError) as exc:
            self.link.dropped(f"{type(exc).__name__}: {str(exc)[:80]}")
            return
        self.put(min(stamp, arrived), xyz)

    def _release(self) -> None:
        self.sock.close()
