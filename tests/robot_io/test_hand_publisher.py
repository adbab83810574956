"""The rehearsal's hand publisher moves the hand as a hand can (issue 25, item 3): a tracked source
refuses a sample that implies a speed beyond ``[hand] max_speed`` as a tracker jump, so the simulated
participant must never teleport. Two moments did: a Go heard late (the application's report reader
kept off the CPU) put the hand mid-reach at once, and the end of a trial put it back at A at once. A
rehearsal under load then ended a reach tracker_lost, '10 samples refused, the latest as a jump of
0.355 m in 0.100 s'."""

from __future__ import annotations

import time

import numpy as np
import pytest
from support.waiting import wait_for

from robot_io.config import ControllerConfig
from robot_io.devices import tracker_transform
from robot_io.hand_publisher import HandPublisher, PublisherSpec
from robot_io.simulated_hand import Scenario
from robot_io.udp_hand import UDPHand

pytestmark = [pytest.mark.slow, pytest.mark.soak]  # a process that publishes on the wall clock

#: This test's own loopback address (UDP port 0: any free one).
HOST = "127.0.0.108"
#: How late the Go reaches the publisher [s]: past the hand's reaction delay (0.15-0.35 s).
LATE_S = 1.0


def test_a_late_go_and_the_end_of_a_trial_move_the_hand_as_a_hand_moves():
    config = ControllerConfig()
    config = config.model_copy(update={"hand_source": config.hand_source.model_copy(
        update={"kind": "udp", "udp_host": HOST, "udp_port": 0})})
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
