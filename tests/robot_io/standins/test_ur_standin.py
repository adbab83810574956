"""The stand-in controller at the wire: RTDE messages from a plain socket, the dashboard's 5 s rule,
and the calibration command that goes with the hardware docs."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
import time

import numpy as np
import pytest
from support.hand_replay import TRACKER, to_tracker
from support.ur import standin
from support.waiting import wait_for

from app.cli import main
from app.session.rig_cli import load_config
from robot_io.standins.ur import rtde_protocol as rtde
from robot_io.standins.ur.dashboard import reply
from robot_io.standins.ur.model import Controller, Safety, Series
from robot_io.standins.ur.rtde_server import RTDEServer

pytestmark = pytest.mark.standin  # the stand-in UR in real time (tests/conftest.py)


def receive(sock: socket.socket) -> tuple[int, bytes]:
    """The next RTDE message the server sends: its type and payload."""
    size, kind = rtde.HEADER.unpack(sock.recv(rtde.HEADER.size, socket.MSG_WAITALL))
    return kind, sock.recv(size - rtde.HEADER.size, socket.MSG_WAITALL)


def request(sock: socket.socket, message_type: int, payload: bytes = b"") -> tuple[int, bytes]:
    sock.sendall(rtde.frame(message_type, payload))
    return receive(sock)


def test_rtde_handshake_recipes_not_found_in_use_and_data_packages_at_the_controller_rate():
    with standin(series="e") as ur:
        host = ur.host
        first = socket.create_connection((host, 30004))
        second = socket.create_connection((host, 30004))
        try:
            assert request(first, rtde.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2))[1] == b"\x01"
            _, version = request(first, rtde.GET_URCONTROL_VERSION)
            assert struct.unpack(">4I", version)[:2] == (5, 11)
            names = b"timestamp,actual_TCP_pose,no_such_variable"
            _, answer = request(first, rtde.SETUP_OUTPUTS, struct.pack(">d", 500.0) + names)
            assert answer[1:].decode().split(",") == ["DOUBLE", "VECTOR6D", "NOT_FOUND"]
            _, answer = request(first, rtde.SETUP_OUTPUTS, struct.pack(">d", 500.0) + names[:-17])
            assert answer[1:] == b"DOUBLE,VECTOR6D"
            _, answer = request(first, rtde.SETUP_INPUTS, b"input_int_register_5")
            assert answer[0] == 1 and answer[1:] == b"INT32"
            _, answer = request(second, rtde.SETUP_INPUTS, b"input_int_register_5")
            assert answer[0] == 0 and answer[1:] == b"IN_USE"
            assert request(first, rtde.START)[1] == b"\x01"
            layout = rtde.recipe_format(["DOUBLE", "VECTOR6D"])
            stamps = []
            for _ in range(50):
                kind, body = receive(first)
                assert kind == rtde.DATA_PACKAGE
                stamps.append(layout.unpack(body[1:])[0])
            assert np.median(np.diff(stamps)) == pytest.approx(0.002)  # 500 Hz controller time
        finally:
            first.close()
            second.close()


def test_dashboard_refuses_to_unlock_a_protective_stop_within_5_s():
    controller = Controller(Series.CB3, np.zeros(6))
    controller.protective_stop("test")
    assert reply(controller, "safetystatus") == "Safetystatus: PROTECTIVE_STOP"
    assert reply(controller, "unlock protective stop").startswith("Cannot unlock protective stop")
    controller.safety_since = time.monotonic() - 5.1
    assert reply(controller, "unlock protective stop") == "Protective stop releasing"
    assert controller.safety is Safety.NORMAL
    assert reply(controller, "PolyscopeVersion").startswith("URSoftware 3.15")
    assert reply(controller, "no such command") == "could not understand: 'no such command'"


def test_calibrate_tracker_prints_the_transform_that_maps_the_pairs(tmp_path, capsys):
    rng = np.random.default_rng(2)
    base = rng.uniform([0.2, -0.4, 0.05], [0.8, 0.4, 0.6], size=(6, 3))
    tracker = np.array([to_tracker(b) for b in base])  # millimetres
    pairs = tmp_path / "pairs.csv"
    np.savetxt(pairs, np.hstack([tracker, base]), delimiter=",", header="tx,ty,tz,bx,by,bz")
    assert main(["calibrate-tracker", str(pairs)]) == 0
    out = capsys.readouterr().out
    assert "units_to_m = 0.001" in out and "RMS residual 0.00 mm" in out
    assert f"translation = [{', '.join(f'{v:.5f}' for v in TRACKER.translation)}]" in out
    # what it prints is a [hand_source] table a lab config takes (its rotation is a proper one)
    config = tmp_path / "lab.toml"
    config.write_text(out)
    assert np.allclose(load_config(config).hand_source.rotation, TRACKER.rotation, atol=1e-6)


def frames(data: bytes) -> list[tuple[int, bytes]]:
    """The whole RTDE messages in ``data`` (a connection cut mid-message leaves a torn last one)."""
    found, at = [], 0
    while at + rtde.HEADER.size <= len(data):
        size, kind = rtde.HEADER.unpack_from(data, at)
        if at + size > len(data):
            break
        found.append((kind, data[at + rtde.HEADER.size:at + size]))
        at += size
    return found


def started_client(server: RTDEServer, names: bytes) -> socket.socket:
    """A client of ``server`` (its side of a socket pair, served in a thread as the listener
    would) with an output recipe of ``names`` at the controller's rate, started."""
    ours, theirs = socket.socketpair()

    def serve() -> None:
        with contextlib.suppress(OSError):  # the connection ended (robot_io.standins.ur.listener)
            server.handle(theirs)

    threading.Thread(target=serve, daemon=True).start()
    assert request(ours, rtde.SETUP_OUTPUTS, struct.pack(">d", 125.0) + names)[1][0] == 1
    assert request(ours, rtde.START)[1] == b"\x01"
    return ours


def test_a_client_that_stops_reading_holds_up_no_other_and_is_disconnected():
    """The cycle broadcasts each package to every client; one that reads nothing (a frozen
    process, a dead link) filled its socket, and the blocking send held the cycle thread and so
    every other client, for good. Now the reader gets every package of every cycle, in order, and
    the silent client is cut off once it has taken nothing for the unread limit, as a real
    controller cuts it off; what it got before is whole packages in order."""
    controller = Controller(Series.CB3, np.zeros(6))
    server = RTDEServer(controller, unread_limit_s=0.5)
    names = b"timestamp,actual_TCP_pose,actual_q,actual_qd,target_q,target_TCP_pose"
    reader, silent = started_client(server, b"timestamp"), started_client(server, names)
    silent.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    cycle, stamps = 0, []

    def cycles() -> bool:
        """Ten cycles of the controller, the reader reading each one's package."""
        nonlocal cycle
        for _ in range(10):
            with controller.lock:
                controller.tick()
            server.broadcast(cycle)
            cycle += 1
            kind, body = receive(reader)
            assert kind == rtde.DATA_PACKAGE
            stamps.append(struct.unpack(">d", body[1:])[0])
        return len(server.connections) == 1

    wait_for(cycles, "the controller to close the connection of the client that reads nothing",
             seen=lambda: f"{cycle} cycles, {len(server.connections)} connections")
    assert np.allclose(np.diff(stamps), controller.period), "the reader missed packages"
    received = b"".join(iter(lambda: silent.recv(65536), b""))  # up to the closed connection
    silent_stamps = [struct.unpack(">d", body[1:9])[0] for kind, body in frames(received)]
    assert 0 < len(silent_stamps) < cycle
    assert np.allclose(np.diff(silent_stamps), controller.period)
    reader.close()
    silent.close()
