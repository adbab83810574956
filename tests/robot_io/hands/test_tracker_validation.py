"""Tracker samples are validated before they are kept, and ``handover check-devices`` judges the
stream: UDP/JSON datagrams on loopback, a real UDPHand, the stand-in controller for the arm."""

from __future__ import annotations

import json
import math
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from support.priority import realtime_threads
from support.ur import standin
from support.waiting import wait_for

from app.cli import main
from robot_io.config import ControllerConfig
from robot_io.devices import tracker_transform
from robot_io.hands.hand import HandSample
from robot_io.hands.tracked_hand import TRACKER_JITTER_M
from robot_io.hands.udp_hand import UDPHand

pytestmark = pytest.mark.standin  # the stand-in UR in real time (tests/conftest.py)

HOST = "127.0.0.1"  # the UDP tests' address (their ports are the kernel's: bound to 0)
HAND_MM = [950.0, 100.0, 50.0]  # A, the hand start, in millimetres


def _free_udp_port(host: str) -> int:
    """A UDP port free on ``host``: check-devices binds the configured port itself (no port 0 in a
    lab file). On the stand-in's own loopback address no other test listens, so a free port stays
    free until check-devices binds it."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


@contextmanager
def sending(address: tuple[str, int], message: Callable[[int], dict],
            period: float = 0.01) -> Iterator[None]:
    """Send ``message(n)`` as JSON to ``address`` every ``period`` (a tracker's pace) until the block
    ends."""
    stop = threading.Event()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def run() -> None:
        n = 0
        while not stop.is_set():
            sock.sendto(json.dumps(message(n)).encode(), address)
            n += 1
            stop.wait(period)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(1.0)
        sock.close()


def _udp_hand() -> UDPHand:
    config = ControllerConfig()
    # port 0: the kernel's free port (no lab configures it, so only a copy takes it)
    source = config.hand_source.as_kind("udp", udp_host=HOST).model_copy(update={"udp_port": 0})
    return UDPHand(source, tracker_transform(config), config.hand.max_speed)


def _newest_after(datagrams: list[bytes]) -> tuple[UDPHand, HandSample | None]:
    """A UDPHand sent ``datagrams`` in order; returns it (closed) and its newest sample."""
    hand = _udp_hand()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for datagram in datagrams:
                sock.sendto(datagram, hand.address)
            wait_for(lambda: hand.received == len(datagrams), f"{len(datagrams)} datagrams received",
                     seen=lambda: hand.received)
        return hand, hand.latest(0.0)
    finally:
        hand.close()


def test_a_nan_stamped_first_datagram_is_one_dropout_not_a_freeze():
    datagrams = [b'{"x": 950.0, "y": 100.0, "z": 50.0, "t": NaN}'] + [
        json.dumps({"x": 950.0 + n, "y": 100.0, "z": 50.0}).encode() for n in range(5)]
    hand, sample = _newest_after(datagrams)
    assert hand.dropouts == 1 and hand.invalid == 1
    assert sample.is_valid() and sample.position[0] == pytest.approx(0.954)


def test_an_implausible_coordinate_is_a_dropout_never_a_hand_position():
    hand, sample = _newest_after([json.dumps({"x": x, "y": 100.0, "z": 50.0}).encode()
                                  for x in (950.0, 1e308)])
    assert hand.dropouts == 1 and hand.invalid == 1
    assert not sample.is_valid()  # the newest sample is a dropout; the loop keeps the last valid
    assert np.all(np.isnan(sample.position))


STREAMS = {
    "7000 s old": (lambda n: {"x": 950.0, "y": 100.0, "z": 50.0, "t": time.monotonic() - 7000.0},
                   "the newest position is 7000"),
    "all occluded": (lambda n: {"x": None, "y": None, "z": None}, "all"),
    "NaN-stamped": (lambda n: {"x": 950.0, "y": 100.0, "z": 50.0, "t": math.nan},
                    "non-finite time stamp"),
    "1e308 mm": (lambda n: {"x": 1e308, "y": 100.0, "z": 50.0}, "implausible position"),
}


def test_check_devices_fails_in_plain_words_on_a_stale_occluded_or_invalid_stream(tmp_path, capsys):
    results = {}
    # The tracker's sender and the check's receiver under SCHED_FIFO (the sender stands for a
    # tracker's own hardware): on the normal policy a loaded full run starved the sender, and the
    # healthy stream's newest sample was 0.143 s old at the check (74 of 100 samples in 1 s).
    with standin() as ur, realtime_threads():
        address = (ur.host, _free_udp_port(ur.host))
        lab = tmp_path / "lab.toml"
        lab.write_text(f'[hand_source]\nkind = "udp"\nudp_host = "{ur.host}"\n'
                       f'udp_port = {address[1]}\n')
        check = ["check-devices", "--ur-host", ur.host, "--config", str(lab)]
        with sending(address, lambda n: {"x": 950.0, "y": 100.0, "z": 50.0}):
            healthy = main(check)
        healthy_out = capsys.readouterr().out
        for name, (message, _) in STREAMS.items():
            with sending(address, message):
                code = main(check)
            results[name] = (code, capsys.readouterr().out)
    assert healthy == 0, healthy_out  # the positive control: the same set-up with a good stream
    assert "hand: udp," in healthy_out
    for name, (code, out) in results.items():
        hand_line = next(line for line in out.splitlines() if line.startswith("hand:"))
        assert code == 1, (name, out)
        assert hand_line.startswith("hand: NOT OK — ") and STREAMS[name][1] in hand_line, name
        assert "arm: UR at" in out and "Traceback" not in out


def _path(n: int, t0: float, y_mm: float = 100.0, x_mm: float | None = None) -> bytes:
    """Sample ``n`` of a hand moving along x at 0.5 m/s (5 mm per 10 ms), stamped ``t0 + n/100``."""
    x = 950.0 + 5.0 * n if x_mm is None else x_mm
    return json.dumps({"x": x, "y": y_mm, "z": 50.0, "t": t0 + 0.01 * n}).encode()


def test_a_tracker_jump_is_refused_until_a_hand_could_have_got_there():
    """2 m added to y for 0.5 s (issue 25, item 3: the trial completed at the speed cap, towards a
    hand 2 m off): every jumped sample is a dropout and says why; the hand back on its path is
    followed again; a position that stays is accepted once hand.max_speed could have carried the
    hand there (a hand that really moved while unseen)."""
    # stamped in the past (a UDPHand takes a stamp in the future as the arrival time)
    t0, max_speed = time.monotonic() - 10.0, ControllerConfig().hand.max_speed
    jumped = [_path(n, t0, y_mm=2100.0) for n in range(10, 60)]
    hand, sample = _newest_after([_path(n, t0) for n in range(10)] + jumped
                                 + [_path(n, t0) for n in range(60, 70)])
    assert (hand.invalid, hand.dropouts) == (50, 50)
    assert re.match(r"a jump of 2\.0\d\d m in 0\.500 s from the last accepted sample \(faster "
                    r"than hand\.max_speed = 3 m/s\)", hand.refusal), hand.refusal
    assert sample.is_valid() and sample.position == pytest.approx(
        tracker_transform(ControllerConfig()).apply(np.array([950.0 + 5 * 69, 100.0, 50.0])))

    stays = range(70, 150)  # 2 m off from sample 69 on, for good
    hand, sample = _newest_after([_path(n, t0) for n in range(70)] + [
        _path(n, t0, y_mm=2100.0, x_mm=950.0 + 5 * 69) for n in stays])
    refused = sum(max_speed * 0.01 * (n - 69) + TRACKER_JITTER_M < 2.0 for n in stays)
    assert hand.invalid == refused == 66
    assert sample.is_valid() and sample.position[1] == pytest.approx(2.1)  # accepted: the new place
