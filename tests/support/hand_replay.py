"""Replaying a simulated participant's hand through a real tracker protocol, in tracker coordinates."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from robot_io.hands.frame import FrameTransform
from robot_io.hands.simulated_hand import SimulatedHand
from support.waiting import CEILING_S, WaitTimeout

#: A tracker frame as a lab might have it: turned 90° about z, offset, in millimetres.
TRACKER = FrameTransform(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
                         np.array([0.5, -0.2, 0.02]), 0.001)


def to_tracker(base_xyz: np.ndarray) -> np.ndarray:
    """Inverse of TRACKER: robot base [m] → tracker [mm]."""
    return TRACKER.rotation.T @ (np.asarray(base_xyz) - TRACKER.translation) / TRACKER.units_to_m


class Replay:
    """Sends ``hand``'s trajectory at ``rate_hz`` via ``send(tracker_xyz)`` until ``stop_after`` s."""

    def __init__(self, hand: SimulatedHand, send: Callable[[np.ndarray], None], rate_hz: float,
                 stop_after: float = 30.0) -> None:
        self.hand, self.send, self.period, self.stop_after = hand, send, 1.0 / rate_hz, stop_after
        self.sent: list[np.ndarray] = []  # robot-base positions, in the order sent
        self._running = True
        self.thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> Replay:
        self.began = time.monotonic()
        self.thread.start()
        return self

    def _run(self) -> None:
        next_at = self.began
        while self._running and time.monotonic() - self.began < self.stop_after:
            position = self.hand.latest(time.monotonic() - self.began).position
            self.send(to_tracker(position))
            self.sent.append(position)
            next_at += self.period
            # Pacing, not waiting: a tracker streams at its rate, so the replay sleeps to the next
            # sample's moment (on a loaded machine it sends late, as a real network may deliver).
            time.sleep(max(0.0, next_at - time.monotonic()))

    def stop(self) -> None:
        """Stop sending and wait for the thread's end (within one period, unless ``send`` hangs:
        the ceiling is for that, and the replay then says so)."""
        self._running = False
        self.thread.join(CEILING_S)
        if self.thread.is_alive():
            raise WaitTimeout(f"the replay's thread did not end within {CEILING_S:g} s of stop(): "
                              f"its send is stuck after {len(self.sent)} samples")
