"""The whole handover cycle of one trial (docs/controller.md), on whatever arm, hand source and gripper the
rig has opened:

    prepare (bounded move to R; the object is put into the open gripper, which closes once the
    experimenter confirms) → loaded → ready (tracker
    alive, hand inside the start zone around A) → go (t = 0) → reach (coupled DMP, eqs. 1–10) → hold
    at H (k_ext compliance, release armed, baseline fresh) → release on the pull, or not_taken after
    [release] timeout_s → retract to R at bounded speed → done.

Each stage is reported as it begins. The two confirmations (object loaded, Go) come from the caller's
:class:`Gates`: the experimenter on the dashboard, or at once with the simulated participant. A stop
request ends any stage, a move to R included: the arm is stopped and nothing more moves. Only a
trial that ended normally (released or not taken) retracts; after a fault, a lost tracker or a stop
the arm stays where it stopped, and the next trial's prepare brings it back within
[ur] max_move_distance.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robot_io.arms.arm import Arm
from robot_io.clock import Clock
from robot_io.config import ControllerConfig
from robot_io.control.loop import HoldPhase, Outcome, StageCallback, StopRequest, TrialRecord, TrialSummary
from robot_io.control.recorder import TrialRecorder
from robot_io.control.release import ForceRelease
from robot_io.control.trial import make_loop
from robot_io.errors import ArmFault, GripperFault, MoveStopped, RobotIOError
from robot_io.grippers.gripper import Gripper
from robot_io.hands.hand import HandSource
from robot_io.stages import Stage
from robot_io.theta import Theta

log = logging.getLogger(__name__)

#: How often the ready check looks at the hand source [s].
READY_POLL_S = 0.01


@dataclass
class Gates:
    """The confirmations a cycle waits for, and the stop request that ends it at any stage."""

    loaded: threading.Event
    go: threading.Event
    stop: StopRequest

    @classmethod
    def automatic(cls) -> Gates:
        """Both confirmations given in advance (the simulated participant, a dry run)."""
        loaded, go = threading.Event(), threading.Event()
        loaded.set()
        go.set()
        return cls(loaded, go, StopRequest())

    def wait(self, gate: threading.Event) -> bool:
        """Block until ``gate`` opens (True) or a stop is requested (False)."""
        while not gate.wait(READY_POLL_S):
            if self.stop.is_set():
                return False
        return not self.stop.is_set()


@dataclass
class CycleDevices:
    arm: Arm
    hand: HandSource
    gripper: Gripper
    clock: Clock


def hand_at_start(hand: HandSource, config: ControllerConfig) -> str | None:
    """None when the tracker is alive and the hand is inside the start zone around A; otherwise why
    not, in plain words. ``hand.latest(0.0)`` dates the newest sample relative to now (t = −age)."""
    sample = hand.latest(0.0)
    limit = config.loop.staleness_limit_s
    if sample is None or not sample.is_valid():
        return "no valid hand sample yet (is the tracker streaming and the marker visible?)"
    if -sample.t > limit:
        return f"the newest hand sample is {-sample.t:.2f} s old (staleness_limit_s = {limit})"
    distance = float(np.linalg.norm(sample.position - config.scene.point("hand_start")))
    if distance > config.cycle.start_zone_m:
        return (f"the hand is {distance:.2f} m from the start A (start_zone_m = "
                f"{config.cycle.start_zone_m}): ask the participant to rest it at A")
    return None


def not_started(config: ControllerConfig, realtime: bool, outcome: Outcome, reason: str) -> TrialRecord:
    """The record of a cycle that ended before Go (nothing streamed)."""
    recorder = TrialRecorder(1)
    summary = TrialSummary(
        outcome=outcome, reason=reason, rate_hz=config.loop.rate_hz,
        realtime=realtime, cycles=0, duration_s=0.0,
        robot_arrival_s=None, hand_arrival_s=None, arrival_gap_s=None, peak_speed_mps=0.0,
        max_tau=config.dmp.tau0, deadline_misses=0, limited_cycles=0, invalid_hand_samples=0,
        compute_us_median=0.0, compute_us_p99=0.0, last_hand_sample_s=None, stop_commanded_s=None)
    return TrialRecord(summary, recorder.columns())


def run_cycle(config: ControllerConfig, theta: Theta | None, devices: CycleDevices, gates: Gates,
              on_stage: StageCallback, recorder: TrialRecorder | None = None,
              on_waiting: Callable[[str | None], None] | None = None) -> TrialRecord:
    """One trial's whole cycle; never raises for what the arm, hand or operator do (it is in the
    outcome). ``on_waiting`` hears, while ready is awaited, why the hand is not ready (None: ready)."""
    arm, hand, gripper, clock = devices.arm, devices.hand, devices.gripper, devices.clock
    realtime = bool(getattr(clock, "realtime", False))
    start = config.scene.point("robot_start")
    release = ForceRelease(config.release, clock.period)
    hold = HoldPhase(release=release, gripper=gripper, read_force=arm.read_force,
                     timeout_s=config.release.timeout_s, linger_s=config.cycle.release_linger_s,
                     settle_speed=config.cycle.hold_settle_speed)
    on_stage(Stage.PREPARE, float("nan"))
    try:
        loop = make_loop(config, theta, hand, arm, clock, hold=hold, on_stage=on_stage,
                         recorder=recorder, stop=gates.stop)
        if not gates.wait(gates.loaded):  # the object goes into the open gripper, at R
            return not_started(config, realtime, Outcome.STOPPED, gates.stop.reason)
        gripper.close()
    except MoveStopped:
        return not_started(config, realtime, Outcome.STOPPED, gates.stop.reason)
    except RobotIOError as exc:
        arm.stop()
        outcome = (Outcome.ARM_FAULT if isinstance(exc, ArmFault) else Outcome.GRIPPER_FAULT
                   if isinstance(exc, GripperFault) else Outcome.ERROR)
        return not_started(config, realtime, outcome, f"prepare: {exc}")
    on_stage(Stage.LOADED, float("nan"))
    waiting = _await_ready(hand, config, gates, on_waiting or (lambda why: None))
    if waiting is not None:
        outcome = Outcome.STOPPED if gates.stop.is_set() else Outcome.TRACKER_LOST
        return not_started(config, realtime, outcome, waiting)
    on_stage(Stage.READY, float("nan"))
    if not gates.wait(gates.go):
        return not_started(config, realtime, Outcome.STOPPED, gates.stop.reason)
    record = loop.run()
    if record.summary.outcome not in (Outcome.COMPLETED, Outcome.NOT_TAKEN):
        return record
    on_stage(Stage.RETRACT, clock.now())
    try:
        arm.move_to(start, gates.stop)
    except MoveStopped:  # stopped on the way back: the next prepare brings it to R
        return record
    except RobotIOError as exc:  # the handover itself happened: it stands; the fault is reported
        log.error("retract to R failed: %s", exc)
        return TrialRecord(record.summary.model_copy(update={"retract_fault": f"retract: {exc}"}),
                           record.samples)
    retract_end = clock.now()
    on_stage(Stage.DONE, retract_end)
    return TrialRecord(record.summary.model_copy(update={"retract_end_s": retract_end}),
                       record.samples)


def _await_ready(hand: HandSource, config: ControllerConfig, gates: Gates,
                 on_waiting: Callable[[str | None], None]) -> str | None:
    """None once the hand is ready; the last reason after ready_timeout_s or a stop."""
    deadline = time.monotonic() + config.cycle.ready_timeout_s
    shown: str | None = "not checked yet"
    while True:
        why = hand_at_start(hand, config)
        if why != shown:
            on_waiting(why)
            shown = why
        if why is None:
            return None
        if gates.stop.is_set():
            return gates.stop.reason
        if time.monotonic() > deadline:
            return f"not ready within ready_timeout_s = {config.cycle.ready_timeout_s} s: {why}"
        time.sleep(READY_POLL_S)
