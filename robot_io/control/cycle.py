"""The whole handover cycle of one trial (docs/controller.md), on whatever arm, hand source and gripper the
rig has opened, as its table says (:mod:`robot_io.control.stages`): the stages before Go one after the
other, each waiting for its entry condition, reported as it begins, doing its work and waiting for its
gate; then the control loop streams from Go (:class:`~robot_io.control.loop.HandoverLoop`); a trial that
ended normally (released or not taken) retracts to R at bounded speed.

The confirmations come from the caller's :class:`Gates`, one per gated stage: the experimenter on the
dashboard, or at once with the simulated participant. A stop request ends any stage, a move to R
included: the arm is stopped and nothing more moves. After a fault, a lost tracker or a stop the arm
stays where it stopped, and the next trial's prepare brings it back within [ur] max_move_distance.
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
from robot_io.control.loop import (
    HandoverLoop,
    HoldPhase,
    Outcome,
    StageCallback,
    StopRequest,
    TrialRecord,
    TrialSummary,
)
from robot_io.control.recorder import TrialRecorder
from robot_io.control.release import ForceRelease
from robot_io.control.stages import CycleTable, Stage, StageRow, Work, current
from robot_io.control.trial import build_loop, make_loop
from robot_io.errors import ArmFault, GripperFault, MoveStopped, RobotIOError
from robot_io.grippers.gripper import Gripper
from robot_io.hands.hand import HandSource
from robot_io.theta import Theta

log = logging.getLogger(__name__)

#: How often the ready check looks at the hand source [s].
READY_POLL_S = 0.01


@dataclass
class Gates:
    """The confirmations a cycle waits for, one per gated stage of its table, and the stop request
    that ends it at any stage."""

    confirmed: dict[str, threading.Event]
    stop: StopRequest

    @classmethod
    def of(cls, cycle: CycleTable, automatic: bool = False) -> Gates:
        """Closed gates for ``cycle``'s gated stages; ``automatic``: all of them given in advance
        (the simulated participant, a dry run)."""
        gates = cls({row.name: threading.Event() for row in cycle.gated}, StopRequest())
        if automatic:
            for gate in gates.confirmed.values():
                gate.set()
        return gates

    @classmethod
    def automatic(cls, cycle: CycleTable | None = None) -> Gates:
        """Every confirmation of ``cycle`` (the one the application runs) given in advance."""
        return cls.of(cycle or current(), automatic=True)

    def confirm(self, stage: str) -> bool:
        """Give the confirmation ``stage`` waits for; False: it waits for none."""
        gate = self.confirmed.get(stage)
        if gate is not None:
            gate.set()
        return gate is not None

    def wait(self, stage: str) -> bool:
        """Block until ``stage``'s confirmation is given (True) or a stop is requested (False)."""
        gate = self.confirmed[stage]
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
              on_waiting: Callable[[str | None], None] | None = None,
              cycle: CycleTable | None = None) -> TrialRecord:
    """One trial's whole ``cycle`` (the one the application runs by default); never raises for what
    the arm, hand or operator do (it is in the outcome). ``on_waiting`` hears, while the hand is
    awaited at the start, why it is not ready (None: ready)."""
    cycle = cycle or current()
    before = BeforeGo(config, theta, devices, gates, on_stage, recorder,
                      on_waiting or (lambda why: None), cycle)
    for row in cycle.before_go:
        ended = before.run(row)
        if ended is not None:
            return ended
    record = before.loop().run()
    if record.summary.outcome not in (Outcome.COMPLETED, Outcome.NOT_TAKEN):
        return record
    return _retract(record, devices, gates.stop, config.scene.point("robot_start"), on_stage)


class BeforeGo:
    """The stages before Go of one trial, run one row of the cycle's table after the other."""

    def __init__(self, config: ControllerConfig, theta: Theta | None, devices: CycleDevices,
                 gates: Gates, on_stage: StageCallback, recorder: TrialRecorder | None,
                 on_waiting: Callable[[str | None], None], cycle: CycleTable) -> None:
        self.config, self.theta, self.devices, self.gates = config, theta, devices, gates
        self.on_stage, self.recorder, self.on_waiting, self.cycle = on_stage, recorder, on_waiting, cycle
        self.realtime = bool(getattr(devices.clock, "realtime", False))
        self._loop: HandoverLoop | None = None
        self._work: dict[Work, Callable[[], str | None]] = {
            Work.MOVE_TO_START: self._move_to_start, Work.CLOSE_GRIPPER: self._close_gripper,
            Work.HAND_AT_START: self._hand_at_start}

    def run(self, row: StageRow) -> TrialRecord | None:
        """Wait for ``row``'s entry condition, report it, do its work, wait for its gate and do
        its exit work; the record of a cycle that ended here (None: it goes on)."""
        if row.awaits is not None and (why := self._work[row.awaits]()) is not None:
            stopped = self.gates.stop.is_set()
            return self._ended(Outcome.STOPPED if stopped else Outcome.TRACKER_LOST, why)
        self.on_stage(row.name, float("nan"))
        try:
            if row.work is not None:
                self._work[row.work]()
            if row.gate is not None and not self.gates.wait(row.name):
                return self._ended(Outcome.STOPPED, self.gates.stop.reason)
            if row.then is not None:
                self._work[row.then]()
        except MoveStopped:
            return self._ended(Outcome.STOPPED, self.gates.stop.reason)
        except RobotIOError as exc:
            self.devices.arm.stop()
            outcome = (Outcome.ARM_FAULT if isinstance(exc, ArmFault) else Outcome.GRIPPER_FAULT
                       if isinstance(exc, GripperFault) else Outcome.ERROR)
            return self._ended(outcome, f"{row.name}: {exc}")
        return None

    def loop(self) -> HandoverLoop:
        """The trial's control loop (made by the move to R, or now, where the arm is)."""
        if self._loop is None:
            self._loop = self._make_loop(move=False)
        return self._loop

    def _make_loop(self, move: bool) -> HandoverLoop:
        config, devices = self.config, self.devices
        hold = HoldPhase(release=ForceRelease(config.release, devices.clock.period),
                         gripper=devices.gripper, read_force=devices.arm.read_force,
                         timeout_s=config.release.timeout_s, linger_s=config.cycle.release_linger_s,
                         settle_speed=config.cycle.hold_settle_speed)
        make = make_loop if move else build_loop
        return make(config, self.theta, devices.hand, devices.arm, devices.clock, hold=hold,
                    on_stage=self.on_stage, recorder=self.recorder, stop=self.gates.stop,
                    cycle=self.cycle)

    def _ended(self, outcome: Outcome, reason: str) -> TrialRecord:
        return not_started(self.config, self.realtime, outcome, reason)

    # -- the work of the stages before Go (robot_io.control.stages.Work) --------------------------
    def _move_to_start(self) -> None:
        """Bounded move to R (the object goes into the open gripper there)."""
        self._loop = self._make_loop(move=True)

    def _close_gripper(self) -> None:
        self.devices.gripper.close()

    def _hand_at_start(self) -> str | None:
        """None once the hand is ready; the last reason after ready_timeout_s or a stop."""
        return _await_ready(self.devices.hand, self.config, self.gates, self.on_waiting)


def _retract(record: TrialRecord, devices: CycleDevices, stop: StopRequest, start: np.ndarray,
             on_stage: StageCallback) -> TrialRecord:
    """retract → done: back to R at bounded speed after a handover (released or not taken)."""
    clock = devices.clock
    on_stage(Stage.RETRACT, clock.now())
    try:
        devices.arm.move_to(start, stop)
    except MoveStopped:  # stopped on the way back: the next prepare brings it to R
        log.warning("retract to R stopped (%s): the trial ends without reaching done", stop.reason)
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
