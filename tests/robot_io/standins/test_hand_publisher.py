"""The rehearsal's hand publisher moves the hand as a hand can (issue 25, item 3): a tracked source
refuses a sample that implies a speed beyond ``[hand] max_speed`` as a tracker jump, so the simulated
participant must never teleport. Two moments did: a Go heard late (the application's report reader
kept off the CPU) put the hand mid-reach at once, and the end of a trial put it back at A at once. A
rehearsal under load then ended a reach tracker_lost, '10 samples refused, the latest as a jump of
0.355 m in 0.100 s'."""

from __future__ import annotations

import contextlib
import random
import socket
import threading
import time

import numpy as np
import pytest
from support.waiting import wait_for

from robot_io.config import ControllerConfig
from robot_io.devices import tracker_transform
from robot_io.hands.simulated_hand import Scenario
from robot_io.hands.udp_hand import UDPHand
from robot_io.standins.hand_publisher import (
    LATE_SUMMARY_S,
    HandPublisher,
    LateSamples,
    PublisherSpec,
)
from robot_io.standins.ur.control import DEFAULT_PORT

pytestmark = [pytest.mark.slow, pytest.mark.soak]  # a process that publishes on the wall clock

#: This test's own loopback address (UDP port 0: any free one).
HOST = "127.0.0.108"
#: How late the Go reaches the publisher [s]: past the hand's reaction delay (0.15-0.35 s).
LATE_S = 1.0


def udp_config() -> ControllerConfig:
    config = ControllerConfig()
    # port 0: the kernel's free port (no lab configures it, so only a copy takes it)
    return config.model_copy(update={"hand_source": config.hand_source.as_kind(
        "udp", udp_host=HOST).model_copy(update={"udp_port": 0})})


def test_a_late_go_and_the_end_of_a_trial_move_the_hand_as_a_hand_moves():
    config = udp_config()
    start = config.scene.point("hand_start")
    source = UDPHand(config.hand_source, tracker_transform(config), config.hand.max_speed)
    publisher = HandPublisher(PublisherSpec(config=config, udp_target=source.address))

    def position() -> np.ndarray:
        sample = source.latest(time.monotonic())
        return np.full(3, np.nan) if sample is None else sample.position

    def away() -> float:
        return float(np.linalg.norm(position() - start))

    try:
        wait_for(lambda: away() < 1e-9, "the hand at rest at A", seen=position)
        publisher.play(Scenario.STRAIGHTFORWARD, seed=3, go_monotonic=time.monotonic() - LATE_S)
        wait_for(lambda: away() > 0.2, "the hand 0.2 m into its reach", seen=position)
        publisher.rest()  # the trial ends mid-reach
        wait_for(lambda: away() < 1e-9, "the hand back at A", seen=position)
    finally:
        publisher.close()
        source.close()
    assert source.received > 0 and source.invalid == 0, source.refusal


class SilentControlPort:
    """A stand-in controller's control port (its fixed port, on a loopback address of its own) that
    reads ``set_hand`` requests and answers none until :meth:`answer`; then it answers each."""

    def __init__(self) -> None:
        self.requests: list[bytes] = []
        self._answering = threading.Event()
        self._listener = socket.socket()
        for _ in range(200):
            self.host = f"127.0.{random.randint(1, 254)}.{random.randint(2, 254)}"
            with contextlib.suppress(OSError):
                self._listener.bind((self.host, DEFAULT_PORT))
                break
        else:
            raise OSError("no free loopback address for a control port")
        self._listener.listen()
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        connection, _ = self._listener.accept()
        self.connection = connection
        # close() shuts the connection down, perhaps under an answer being sent: that ends it
        with connection, connection.makefile("rb") as lines, contextlib.suppress(OSError):
            for line in lines:
                self.requests.append(line)
                self._answering.wait()
                connection.sendall(b'{"ok": true}\n')

    def answer(self) -> None:
        self._answering.set()

    def close(self) -> None:
        """End the controller (its connection and its port), as a Ctrl-C does."""
        with contextlib.suppress(AttributeError, OSError):
            self.connection.shutdown(socket.SHUT_RDWR)
        self._listener.close()


def test_the_stream_goes_on_while_the_standin_controller_is_slow_to_answer_and_ends_with_it():
    """The publisher told the stand-in where the hand is and waited for its answer before the next
    sample, so a stand-in slow to answer (its control thread shares one interpreter lock with its
    controller cycle) held the tracker stream. A real tracker does not wait on the robot."""
    config = udp_config()
    source = UDPHand(config.hand_source, tracker_transform(config), config.hand.max_speed)
    port = SilentControlPort()
    publisher = HandPublisher(PublisherSpec(config=config, udp_target=source.address,
                                            standin_host=port.host))

    def seen() -> str:
        return (f"{source.received} samples; {len(port.requests)} set_hand requests, none answered; "
                f"publisher alive: {publisher.process.is_alive()}")

    try:
        wait_for(lambda: port.requests, "the publisher's first set_hand", seen=seen)
        asked = source.received
        # 30 samples (0.3 s at 100 Hz) while the first request still waits for its answer
        wait_for(lambda: source.received >= asked + 30, "30 more samples with set_hand unanswered",
                 seen=seen)
        assert len(port.requests) == 1, seen()  # one request at a time, as the port expects
        port.answer()
        wait_for(lambda: len(port.requests) >= 3, "set_hand again once answered", seen=seen)
        port.close()
        wait_for(lambda: not publisher.process.is_alive(), "the publisher ended with the stand-in",
                 seen=seen)
    finally:
        port.close()
        publisher.close()
        source.close()


def test_late_samples_are_said_once_with_advice_then_counted():
    """"hand publisher: a sample 448 ms late" came with no advice, once per late sample (issue 45,
    item 16): the first says what it means for the rehearsal and what to do; the ones after it
    are counted and said at most every LATE_SUMMARY_S."""
    late = LateSamples()
    first = late.note(0.448, now=100.0)
    assert first == (
        "rehearsal's hand publisher: a sample went out 448 ms late (its tracker rate is "
        "not kept): this computer is too busy for the rehearsal's stand-ins. Close other programs; "
        "a trial that ends tracker_lost now says so about the rehearsal, not the rig")
    assert late.note(0.06, now=100.5) is None and late.note(0.2, now=101.0) is None
    assert late.note(0.07, now=100.0 + LATE_SUMMARY_S) == (
        f"rehearsal's hand publisher: 3 more samples went out late in the last "
        f"{LATE_SUMMARY_S:.0f} s, by up to 200 ms")
    assert late.note(0.06, now=101.0 + LATE_SUMMARY_S) is None
