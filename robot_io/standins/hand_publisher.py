"""The rehearsal's simulated participant as a tracker would deliver them: a process that plays the
simulated hand (:class:`~robot_io.hands.simulated_hand.SimulatedHand`) on a Lab Streaming Layer outlet,
as UDP datagrams and/or as the rigid body of a stand-in NatNet server
(:mod:`robot_io.standins.natnet`), in tracker coordinates (the inverse of ``[hand_source]``'s calibration), at
the tracker rate, and tells a stand-in UR controller where the hand is so that it pulls on the object
(:mod:`robot_io.hands.simulated_pull`).

Between trials the hand rests at the start A (so the cycle's ready check passes); :meth:`play` starts
a trial's trajectory at the Go instant, on this machine's monotonic clock, which is also LSL's. The
hand moves as a hand can, never faster than ``[hand] max_speed``, or a tracked source would refuse
its samples as tracker jumps: after a trial it walks back to A (``WALK_SPEED_MPS``), and a Go heard
after the hand should have left A (this process or the application was kept off the CPU) starts the
reach as it is heard, as a participant who reacts late, rather than in the middle of its path.
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import socket
import threading
import time
import uuid
from multiprocessing.connection import Connection

import numpy as np
from pydantic import BaseModel, ConfigDict

from robot_io.child_signals import ignore_interrupts, interrupts_held
from robot_io.clock import SUPPORT_PRIORITY, raise_priority
from robot_io.config import ControllerConfig
from robot_io.devices import tracker_transform
from robot_io.hands.config import LSLSource
from robot_io.hands.frame import FrameTransform
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.minimum_jerk import minimum_jerk

log = logging.getLogger(__name__)

#: The mean speed of the hand's walk back to A after a trial [m/s] (a minimum-jerk move: it peaks
#: at 15/8 of this, well below [hand] max_speed).
WALK_SPEED_MPS = 0.5


class Walk:
    """The hand's minimum-jerk move from where it is to ``end`` at WALK_SPEED_MPS, from ``began``."""

    def __init__(self, start: np.ndarray, end: np.ndarray, began: float) -> None:
        self.start, self.end, self.began = start, end, began
        self.duration = max(float(np.linalg.norm(end - start)) / WALK_SPEED_MPS, 1e-3)

    def at(self, now: float) -> np.ndarray:
        return minimum_jerk(self.start, self.end, self.duration, np.array([now - self.began]))[0][0]


class PublisherSpec(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    config: ControllerConfig
    lsl_name: str | None = None  # publish an LSL stream of [hand_source] lsl_stream_type
    udp_target: tuple[str, int] | None = None  # send UDP datagrams there
    standin_host: str | None = None  # report the hand to this stand-in's control port
    natnet_rigid_body: str | None = None  # serve NatNet on 127.0.0.1 (a free port): this rigid body
    realtime_priority: bool = False  # SCHED_FIFO: a tracker has hardware of its own


def _serve(conn: Connection, spec: PublisherSpec) -> None:
    # Ctrl-C in the terminal reaches the whole process group: the application closes the publisher
    # (its pipe), so the publisher itself ignores it rather than print a traceback at every exit
    # (held since HandPublisher started it, child_signals)
    ignore_interrupts()
    import pylsl

    from robot_io.standins.ur.control import ControlClient

    if spec.realtime_priority:
        raise_priority(SUPPORT_PRIORITY)
    config = spec.config
    transform = tracker_transform(config)
    outlet = None
    if spec.lsl_name is not None:
        source = config.hand_source
        assert isinstance(source, LSLSource), "an LSL stream is published for an LSL hand source"
        # a source_id of its own: no other outlet (another rehearsal, a test) can be taken for it
        info = pylsl.StreamInfo(spec.lsl_name, source.lsl_stream_type, 3,
                                config.hand.tracker_rate_hz,
                                pylsl.cf_double64, f"{spec.lsl_name}-{uuid.uuid4().hex}")
        outlet = pylsl.StreamOutlet(info)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM) if spec.udp_target else None
    standin = ControlClient(spec.standin_host) if spec.standin_host else None
    # where the NatNet stand-in's next frame puts the hand and when it was there (the loop below
    # moves it; one tuple, replaced whole, so the stand-in's thread reads a consistent pair)
    natnet_tracker = [(time.monotonic(), transform.invert(config.scene.point("hand_start")))]
    natnet = _natnet_standin(spec, transform, natnet_tracker)
    conn.send(("ready", None if natnet is None else natnet.address[1]))
    try:
        _play(conn, spec, transform, outlet, udp, standin, natnet_tracker)
    finally:
        if natnet is not None:
            natnet.close()


def _natnet_standin(spec: PublisherSpec, transform: FrameTransform,
                    tracker: list[tuple[float, np.ndarray]]):
    """A NatNet stand-in on 127.0.0.1 streaming ``tracker[0]`` (when, where) as
    ``spec.natnet_rigid_body``, beside a second rigid body (the object, at H) so the source must
    choose by name; None without one."""
    if spec.natnet_rigid_body is None:
        return None
    from robot_io.standins.natnet import NatNetStandin, RigidBodySpec, Snapshot, pose_at

    config = spec.config
    held = pose_at(transform.invert(config.scene.point("handover_point")))
    bodies = [RigidBodySpec(spec.natnet_rigid_body, 1), RigidBodySpec(REHEARSAL_OBJECT, 2)]

    def poses() -> Snapshot:
        measured_at, position = tracker[0]
        return Snapshot({1: pose_at(position), 2: held}, measured_at)

    return NatNetStandin(bodies, poses, rate_hz=config.hand.tracker_rate_hz).start()


#: The name of the NatNet stand-in's second rigid body in a rehearsal.
REHEARSAL_OBJECT = "handover-object"


class HandReport:
    """Tells a stand-in UR controller where the hand is (``set_hand``, for its simulated pull) from a
    thread of its own, newest position first: the tracker's stream never waits on the controller's
    answer, as a real tracker, with hardware of its own, does not. A stand-in slow to answer (its
    threads share one interpreter lock with its controller cycle) had held every sample behind it.

    :attr:`ended` is set when the stand-in has gone (e.g. Ctrl-C): so has the rehearsal."""

    def __init__(self, standin) -> None:
        self._standin = standin
        self._newest: list[float] | None = None
        self._changed = threading.Condition()
        self.ended = threading.Event()
        threading.Thread(target=self._send, name="hand-report", daemon=True).start()

    def put(self, position: list[float]) -> None:
        """Report ``position`` next, in place of any position not yet sent."""
        with self._changed:
            self._newest = position
            self._changed.notify()

    def _send(self) -> None:
        while True:
            with self._changed:
                self._changed.wait_for(lambda: self._newest is not None)
                position, self._newest = self._newest, None
            try:
                self._standin("set_hand", position=position)
            except (OSError, ValueError):
                self.ended.set()
                return


#: A sample that goes out this late [s] is logged (half the rig's default staleness limit), so a
#: rehearsal ended tracker_lost says whether its tracker was late.
LATE_WARNING_S = 0.05
#: After the first late sample, the late ones are counted and said at most this often [s].
LATE_SUMMARY_S = 10.0


class LateSamples:
    """What to log of the publisher's late samples: the first with what it means and what to do,
    then a count at most every LATE_SUMMARY_S (one line per late sample filled a busy rehearsal's
    terminal)."""

    def __init__(self) -> None:
        self._said_at: float | None = None
        self._count, self._worst = 0, 0.0

    def note(self, late_s: float, now: float) -> str | None:
        """A sample went out ``late_s`` late at ``now``: the line to log, if any."""
        if self._said_at is None:
            self._said_at = now
            return (f"rehearsal's hand publisher: a sample went out {1e3 * late_s:.0f} ms late (its "
                    "tracker rate is not kept): this computer is too busy for the rehearsal's "
                    "stand-ins. Close other programs; a trial that ends tracker_lost now says so "
                    "about the rehearsal, not the rig")
        self._count, self._worst = self._count + 1, max(self._worst, late_s)
        if now - self._said_at < LATE_SUMMARY_S:
            return None
        line = (f"rehearsal's hand publisher: {self._count} more sample"
                f"{'s' if self._count != 1 else ''} went out late in the last "
                f"{now - self._said_at:.0f} s, by up to {1e3 * self._worst:.0f} ms")
        self._said_at, self._count, self._worst = now, 0, 0.0
        return line


def _play(conn: Connection, spec: PublisherSpec, transform: FrameTransform, outlet,
          udp: socket.socket | None, standin, natnet_tracker: list[tuple[float, np.ndarray]]) -> None:
    """Play the hand until the pipe closes (or the stand-in controller ends)."""
    import pylsl

    config = spec.config
    report = None if standin is None else HandReport(standin)
    rate = config.hand.tracker_rate_hz
    rest = config.scene.point("hand_start")
    hand: SimulatedHand | None = None
    walk: Walk | None = None  # back to A after a trial
    exact = rest  # where the hand is
    go, occluded_until = 0.0, 0.0
    next_at = time.monotonic()
    late_samples = LateSamples()
    while True:
        if (late := time.monotonic() - next_at) > LATE_WARNING_S:
            if (line := late_samples.note(late, time.monotonic())) is not None:
                log.warning("%s", line)
            next_at += late  # as a tracker, it skips the frames it missed rather than burst them
        while conn.poll():
            try:
                message = conn.recv()
            except (EOFError, OSError):
                return
            if message[0] == "play":
                _, scenario, seed, go = message
                hand = SimulatedHand(Scenario(scenario), config.scene, config.hand, seed)
                # a Go heard after the hand should have left A: it leaves now (a late reaction)
                go = max(go, time.monotonic() - hand.reaction_delay)
            elif message[0] == "occlude":
                occluded_until = time.monotonic() + message[1]
            else:
                hand, walk = None, Walk(exact, rest, time.monotonic())
        now = time.monotonic()
        if hand is not None and now >= go:
            sample = hand.latest(now - go)
            position = np.full(3, np.nan) if sample is None else sample.position
            exact = hand.position_at(now - go)
        else:
            position = exact = rest if walk is None else walk.at(now)
        if now < occluded_until:
            position = np.full(3, np.nan)  # the marker is hidden: the tracker sends no position
        tracker = transform.invert(position)
        natnet_tracker[0] = (now, tracker)
        if outlet is not None:
            outlet.push_sample(tracker.tolist(), pylsl.local_clock())
        if udp is not None and spec.udp_target is not None:
            datagram = {axis: (None if not np.isfinite(v) else float(v))
                        for axis, v in zip("xyz", tracker, strict=True)}
            udp.sendto(json.dumps(datagram | {"t": now}).encode(), spec.udp_target)
        if report is not None:
            if report.ended.is_set():
                return
            report.put(exact.tolist())
        next_at += 1.0 / rate
        time.sleep(max(0.0, next_at - time.monotonic()))


#: How long the publisher may take to start (a fresh interpreter importing numpy and pylsl): on a
#: busy 2-core machine this took over 10 s, which ended rehearsals before they began.
START_TIMEOUT_S = 30.0


class HandPublisher:
    """Runs :func:`_serve` in a process of its own; it exits when this object's process ends."""

    def __init__(self, spec: PublisherSpec, timeout: float = START_TIMEOUT_S) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, spec), name="hand-publisher",
                                       daemon=True)
        with interrupts_held():
            self.process.start()
        child.close()
        ready = self._conn.recv() if self._conn.poll(timeout) else None
        if not (isinstance(ready, tuple) and ready[0] == "ready"):
            self.close()
            raise RuntimeError(f"the hand publisher did not start within {timeout:g} s")
        #: the NatNet stand-in's command port on 127.0.0.1 (None: no NatNet)
        self.natnet_port: int | None = ready[1]

    def play(self, scenario: Scenario, seed: int, go_monotonic: float) -> None:
        """Play a trial's hand from the Go instant ``go_monotonic`` (``time.monotonic()``)."""
        self._conn.send(("play", scenario.value, seed, go_monotonic))

    def rest(self) -> None:
        """Back to the start A."""
        self._conn.send(("rest",))

    def occlude(self, seconds: float) -> None:
        """Hide the marker for ``seconds``: the tracker sends occluded (NaN) samples (rehearsing a
        lost tracker; the hand itself goes on)."""
        self._conn.send(("occlude", seconds))

    def close(self) -> None:
        self._conn.close()
        self.process.join(2.0)
        if self.process.is_alive():
            self.process.kill()
