"""A tracker with a process of its own: an LSL outlet replaying a simulated participant's hand (in
tracker coordinates, :mod:`support.hand_replay`) from a spawned process, under SCHED_FIFO where the
OS allows it, as a motion-capture machine streams it to the lab's.

In the test process the outlet's thread shared one interpreter lock with the hand source's receiver
and the control loop it feeds: beside two suites on two cores a gap of 0.106 s there ended a trial
tracker_lost (staleness_limit_s = 0.1), as the product must. A tracker has hardware of its own; here
it has a process of its own, and the test process holds only what a rig process holds.
"""

from __future__ import annotations

import multiprocessing
from multiprocessing.connection import Connection

import numpy as np

from robot_io.clock import SUPPORT_PRIORITY, raise_priority
from robot_io.config import ControllerConfig
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from support.hand_replay import Replay
from support.waiting import CEILING_S, WaitTimeout


def _stream(conn: Connection, info: tuple[str, str, str], scenario: Scenario,
            config: ControllerConfig, seed: int, rate_hz: float) -> None:
    """The tracker process: open the outlet, say "ready", replay from "start" until "stop", then
    send back the positions sent (robot base frame, in order)."""
    import pylsl

    raise_priority(SUPPORT_PRIORITY)
    name, stream_type, source_id = info
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, stream_type, 3, rate_hz, pylsl.cf_float32,
                                                 source_id))
    conn.send("ready")
    if conn.recv() != "start":
        return
    hand = SimulatedHand(scenario, config.scene, config.hand, seed)
    replay = Replay(hand, lambda xyz: outlet.push_sample(xyz.tolist()), rate_hz).start()
    try:
        conn.recv()  # "stop", or the test process is gone (EOFError)
    finally:
        replay.stop()
    conn.send(np.array(replay.sent))


class LSLTracker:
    """The stream ``name`` of type ``stream_type`` and ``source_id``, replaying ``scenario``'s hand at
    ``rate_hz`` once :meth:`start` is called; open (resolvable) when the constructor returns."""

    def __init__(self, name: str, stream_type: str, source_id: str, scenario: Scenario,
                 config: ControllerConfig, seed: int, rate_hz: float = 100.0) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self.process = context.Process(target=_stream, name="lsl-tracker", daemon=True,
                                       args=(child, (name, stream_type, source_id), scenario,
                                             config, seed, rate_hz))
        self.process.start()
        child.close()
        self._expect("its outlet open")

    def _expect(self, what: str) -> object:
        if not self._conn.poll(CEILING_S):
            raise WaitTimeout(f"gave up after {CEILING_S:g} s waiting for the tracker process "
                              f"(pid {self.process.pid}) to report {what}; alive: "
                              f"{self.process.is_alive()}, exit code {self.process.exitcode}")
        return self._conn.recv()

    def start(self) -> None:
        self._conn.send("start")

    def stop(self) -> np.ndarray:
        """Stop streaming; the positions sent (robot base frame), in the order sent."""
        self._conn.send("stop")
        sent = self._expect("the samples it sent")
        self.process.join(CEILING_S)
        return sent

    def close(self) -> None:
        if self.process.is_alive():
            self.process.kill()
            self.process.join(CEILING_S)
        self._conn.close()
