"""The NatNet stand-in (robot_io.standins.natnet) as OptiTrack's own Python client (``natnetsdk``,
its NatNetClient.py) reads it, at each protocol Motive streams: 3.1 (Motive 2.x), 4.0 (Motive 3.0)
and 4.1 (Motive 3.1 and later). The client composes the requests and decodes the answers and frames
that come back over real UDP; every byte of each packet is read, and what it decodes is what the
stand-in was given."""

from __future__ import annotations

import math
import socket
import struct

import numpy as np
import pytest
from natnetsdk.NatNetClient import NatNetClient
from support.natnet import HAND, OBJECT, motive
from support.waiting import wait_for

from robot_io.standins.natnet import (
    CLOCK_HZ,
    MOTIVE_OF,
    NAT_FRAMEOFDATA,
    NAT_MODELDEF,
    NAT_SERVERINFO,
    RigidBodyPose,
    hidden,
)

pytestmark = pytest.mark.soak  # real sockets and threads on the clock: `make soak` repeats them

HAND_AT, OBJECT_AT = (0.25, 1.1, -0.4), (0.5, 0.9, 0.1)  # tracker frame [m]


def poses() -> dict[int, RigidBodyPose]:
    return {HAND.id: RigidBodyPose(HAND_AT, (0.0, 0.0, 0.6, 0.8), mean_error=0.0004),
            OBJECT.id: hidden()}


class Exchange:
    """A socket of the test's own on which OptiTrack's client sends its requests to the stand-in;
    the packets that come back are handed to that client's own decoders."""

    def __init__(self, server) -> None:
        self.server, self.client = server, NatNetClient()
        self.client.set_use_multicast(False)
        self.client.set_print_level(0)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)

    def request(self, command: int) -> None:
        self.client.send_request(self.sock, command, "", self.server.address)

    def next_packet(self, message: int) -> bytes:
        """The next packet of type ``message`` from the stand-in (its header checked)."""
        got: list[bytes] = []

        def arrived() -> bool:
            try:
                packet = self.sock.recv(65536)
            except TimeoutError:
                return False
            got.append(packet)
            return struct.unpack_from("<H", packet)[0] == message

        wait_for(arrived, f"a packet of type {message} from the stand-in",
                 seen=lambda: [struct.unpack_from("<H", packet)[0] for packet in got])
        packet = got[-1]
        assert struct.unpack_from("<H", packet, 2)[0] == len(packet) - 4
        return packet

    def decode(self, name: str, packet: bytes):
        """OptiTrack's decoder ``name`` on ``packet``'s payload at the protocol the client took from
        the server; the payload's whole length must be read."""
        major, minor = self.client.get_major(), self.client.get_minor()
        read, decoded = getattr(self.client, f"_NatNetClient__{name}")(packet[4:], len(packet) - 4,
                                                                        major, minor)
        assert read == len(packet) - 4, f"{name} read {read} of {len(packet) - 4} bytes"
        return decoded

    def close(self) -> None:
        self.sock.close()


@pytest.mark.parametrize("protocol", MOTIVE_OF, ids=lambda protocol: "NatNet {}.{}".format(*protocol))
def test_optitracks_own_client_decodes_the_server_its_bodies_and_their_frames(protocol):
    with motive(poses, protocol=protocol) as server:
        exchange = Exchange(server)
        try:
            exchange.request(NatNetClient.NAT_CONNECT)
            info = exchange.next_packet(NAT_SERVERINFO)
            # the server info sets the protocol the client decodes with, as when it runs
            exchange.client._NatNetClient__unpack_server_info(info[4:], len(info) - 4, 0, 0)
            exchange.request(NatNetClient.NAT_REQUEST_MODELDEF)
            descriptions = exchange.decode("unpack_data_descriptions", exchange.next_packet(NAT_MODELDEF))
            frame = exchange.decode("unpack_mocap_data", exchange.next_packet(NAT_FRAMEOFDATA))
        finally:
            exchange.close()
    assert (exchange.client.get_major(), exchange.client.get_minor()) == protocol
    assert exchange.client.get_application_name() == "Motive"
    assert [(body.sz_name, body.id_num) for body in descriptions.rigid_body_list] == [
        (b"hand", HAND.id), (b"object", OBJECT.id)]
    bodies = {body.id_num: body for body in frame.rigid_body_data.rigid_body_list}
    assert sorted(bodies) == [HAND.id, OBJECT.id]
    hand = bodies[HAND.id]
    assert hand.tracking_valid and not bodies[OBJECT.id].tracking_valid
    assert np.allclose(hand.pos, HAND_AT, atol=1e-6) and np.allclose(hand.rot, (0.0, 0.0, 0.6, 0.8))
    assert hand.error == pytest.approx(0.0004)
    suffix = frame.suffix_data
    latency = (suffix.stamp_transmit - suffix.stamp_camera_mid_exposure) / CLOCK_HZ
    assert latency == pytest.approx(server.latency_s, abs=1e-6)
    if protocol >= (4, 0):  # the precision time stamp: the frame's time stamp in whole seconds + fraction
        seconds = suffix.prec_timestamp_secs + (suffix.prec_timestamp_frac_secs % 2**32) / 2**32
        assert suffix.prec_timestamp_secs == math.floor(suffix.timestamp)
        assert seconds == pytest.approx(suffix.timestamp, abs=1e-6)
    assert suffix.param == 0
