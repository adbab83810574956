"""The control loop of one handover (docs/controller.md): per cycle, read the latest hand sample → distance
filter (6, 7) → coupling (8–10) → DMP step (1–5) → safety limiter → arm; one recorded row per cycle.

The loop runs on a real or a simulated clock through the same code. It ends when the robot is at the
handover point with the hand arrived and the robot settled, on timeout, on a stale hand source, on an
arm fault, on request, or on any exception; in every case the arm is told to stop and the loop waits,
boundedly, until it is at rest.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from pydantic import BaseModel

from robot_io.arms.arm import Arm, ArmState
from robot_io.clock import Clock
from robot_io.config import LoopConfig
from robot_io.control.compliance import signals_source
from robot_io.control.coupling import Coupling
from robot_io.control.dmp import DMP
from robot_io.control.recorder import SLICES, TrialRecorder
from robot_io.control.release import ForceRelease
from robot_io.control.safety import SafetyLimiter
from robot_io.control.stages import CycleTable, Stage, current
from robot_io.errors import ArmFault, GripperFault
from robot_io.grippers.gripper import Gripper
from robot_io.hands.hand import HandSample, HandSource
from robot_io.vector import norm

#: Hears each stage (its name) as it begins, with its time in seconds after Go (NaN before Go).
StageCallback = Callable[[str, float], None]

log = logging.getLogger(__name__)

#: Robot speed [m/s] below which a robot at the handover point counts as settled.
SETTLE_SPEED = 0.02
#: How long [s] the loop waits for the arm to come to rest after stop().
STOP_CONFIRM_S = 1.0


class Outcome(StrEnum):
    COMPLETED = "completed"  # with a hold phase: the object was released on the participant's pull
    NOT_TAKEN = "not_taken"  # held out, but no pull within [release] timeout_s
    TIMEOUT = "timeout"
    TRACKER_LOST = "tracker_lost"
    ARM_FAULT = "arm_fault"
    GRIPPER_FAULT = "gripper_fault"  # it stopped answering, reported a fault or lost the object
    STOPPED = "stopped"  # on request (experimenter's Stop)
    ERROR = "error"


class TrialSummary(BaseModel):
    """What one handover came to; ``arrival_gap_s`` = robot − hand arrival (> 0: robot late)."""

    outcome: Outcome
    reason: str | None = None
    rate_hz: float
    realtime: bool
    cycles: int
    duration_s: float
    robot_arrival_s: float | None
    hand_arrival_s: float | None
    arrival_gap_s: float | None
    peak_speed_mps: float
    max_tau: float
    deadline_misses: int
    limited_cycles: int
    invalid_hand_samples: int
    compute_us_median: float
    compute_us_p99: float
    last_hand_sample_s: float | None
    stop_commanded_s: float | None
    first_target_s: float | None = None
    hold_s: float | None = None
    release_s: float | None = None
    peak_pull_n: float | None = None
    retract_end_s: float | None = None
    retract_fault: str | None = None  # the retract to R failed after the handover: why


@dataclass
class HoldPhase:
    """What the loop needs to hold the object out at H and let go on the participant's pull:
    the force-threshold release (armed only while holding), the gripper, and how long to wait."""

    release: ForceRelease
    gripper: Gripper
    read_force: Callable[[], np.ndarray]
    timeout_s: float
    linger_s: float
    settle_speed: float


@dataclass
class TrialRecord:
    summary: TrialSummary
    samples: dict[str, np.ndarray]


@dataclass
class Handover:
    """What one handover has come to so far: its stage, its times (seconds after Go) and how it
    ended. The loop's thread writes it, one control cycle at a time."""

    reason: str | None
    outcome: Outcome = Outcome.TIMEOUT
    stage: str = Stage.GO
    steering: bool = False  # the coupling was reset on the first hand sample
    measured: np.ndarray | None = None  # the TCP the previous cycle measured
    first_target: float | None = None
    robot_arrival: float | None = None
    hand_arrival: float | None = None
    hold_at: float | None = None
    release_at: float | None = None
    peak_pull: float = 0.0

    def end(self, outcome: Outcome, reason: str | None = None) -> bool:
        """The handover ended with ``outcome``; True (the loop's "it ended")."""
        self.outcome, self.reason = outcome, reason
        return True


class StopRequest(threading.Event):
    """A request to stop the arm, and why (:attr:`reason`: the first request's)."""

    def __init__(self) -> None:
        super().__init__()
        self.reason = "stop requested"

    def request(self, reason: str) -> None:
        """Request the stop; a reason given after the first request does not replace it."""
        if not self.is_set():
            self.reason = reason
            self.set()


class HandoverLoop:
    """One handover: call :meth:`run` on this thread, or :meth:`start` for a worker thread.

    Without a ``hold`` phase the loop ends when robot and hand are both at H and the robot is still
    (one reach, Fig. 4). With one, it goes on streaming at H: the hold begins when the robot is at H
    and still, the release is armed, the coupling adds the k_ext compliance term while the object is
    grasped (``coupling`` should be a :class:`~robot_io.control.compliance.CompliantCoupling` over the same
    release), and the loop ends ``linger_s`` after the gripper opens, or ``not_taken`` after
    ``timeout_s`` of holding without a pull. ``on_stage`` hears each stage as it begins; ``stop``,
    if given, is the event that requests a stop (shared with whoever owns the trial).
    """

    def __init__(self, dmp: DMP, coupling: Coupling, hand: HandSource, arm: Arm, clock: Clock,
                 limiter: SafetyLimiter, config: LoopConfig, hold: HoldPhase | None = None,
                 on_stage: StageCallback | None = None,
                 recorder: TrialRecorder | None = None,
                 stop: StopRequest | None = None, cycle: CycleTable | None = None) -> None:
        self.dmp, self.coupling, self.hand, self.arm = dmp, coupling, hand, arm
        self._signals = signals_source(coupling)  # recorded every cycle, through the compliance
        self.clock, self.limiter, self.config = clock, limiter, config
        self.hold, self.on_stage = hold, on_stage or (lambda stage, t: None)
        self._stop_requested = stop or StopRequest()
        self._thread: threading.Thread | None = None
        self.result: TrialRecord | None = None
        self._recorder: TrialRecorder | None = recorder
        self._cycle_table = cycle or current()
        steps: dict[str, Callable[[Handover, float, float, np.ndarray], bool]] = {
            Stage.GO: self._going, Stage.REACH: self._reaching, Stage.HOLD: self._holding,
            Stage.RELEASE: self._releasing}
        if missing := self._cycle_table.streamed - set(steps):
            raise ValueError(f"the control loop has no step for the streamed stages {sorted(missing)}")
        self._steps = {name: steps[name] for name in self._cycle_table.streamed}

    # -- threading --------------------------------------------------------------------------------
    def start(self) -> threading.Thread:
        """Run the handover in a worker thread; :attr:`result` is set when it ends."""
        self._thread = threading.Thread(target=self.run, name="handover-loop", daemon=True)
        self._thread.start()
        return self._thread

    def request_stop(self) -> None:
        """Stop the handover: the arm is told to stop within one cycle."""
        self._stop_requested.set()

    def join(self, timeout: float | None = None) -> TrialRecord | None:
        if self._thread is not None:
            self._thread.join(timeout)
        return self.result

    def latest(self, stride: int = 1) -> dict[str, np.ndarray] | None:
        """The rows recorded so far (every ``stride``-th), read from another thread while the loop
        runs (live displays); None before the loop started. Costs the loop nothing."""
        recorder = self._recorder
        return None if recorder is None else recorder.view(stride)

    # -- the loop ---------------------------------------------------------------------------------
    def run(self) -> TrialRecord:
        """Stream the handover: one control cycle after the other, each running its stage's step
        (:data:`robot_io.control.stages.PAPER_CYCLE`'s streamed stages), until one ends it."""
        cfg, clock = self.config, self.clock
        if self._recorder is None:
            hold = self.hold
            held = 0.0 if hold is None else hold.timeout_s + hold.linger_s
            self._recorder = TrialRecorder(int((cfg.timeout_s + held + 1.0) * cfg.rate_hz))
        recorder = self._recorder
        self._last: HandSample | None = None
        self._seen_t = -np.inf
        self._invalid = 0
        self._refused_before = getattr(self.hand, "invalid", 0)  # a tracked hand's refusals so far
        handover = Handover(reason=f"no handover within timeout_s = {cfg.timeout_s}")
        misses, lateness = 0, 0.0
        clock.start()
        self.on_stage(Stage.GO, 0.0)
        try:
            self.arm.begin_stream()
            self.limiter.reset(self.arm.read_pose())
            self.dmp.reset()
            # starting the stream waits for the controller (a few ms on a UR): the 500 Hz grid
            # begins with the first cycle, so that wait does not make the first cycles late
            clock.align()
            while not self._cycle(handover, recorder.next_row, lateness):
                lateness, missed = clock.wait_next_cycle()
                misses += missed
        except ArmFault as exc:
            handover.end(Outcome.ARM_FAULT, self.arm.fault or str(exc))
        except GripperFault as exc:
            handover.end(Outcome.GRIPPER_FAULT, str(exc))
        except Exception as exc:
            log.exception("handover loop failed")
            handover.end(Outcome.ERROR, f"{type(exc).__name__}: {exc}")
        finally:
            recorder.finish()  # no row follows while the arm is stopped (a rig's watcher knows)
            stop_at = self._halt()
            clock.stop()
        samples = recorder.columns()
        summary = self._summarise(samples, handover, misses, stop_at)
        self.result = TrialRecord(summary, samples)
        log.info("handover ended: %s (%s)", handover.outcome, handover.reason)
        return self.result

    def _cycle(self, handover: Handover, next_row: Callable[[], np.ndarray], lateness: float) -> bool:
        """One control cycle: read the hand and the arm, steer, record the row, run the stage's
        step. True: the handover ended (its outcome is in ``handover``)."""
        cfg, hold = self.config, self.hold
        t = self.clock.now()
        began = time.perf_counter()
        if self._stop_requested.is_set():
            return handover.end(Outcome.STOPPED, self._stop_requested.reason)
        if self.arm.state is ArmState.FAULT:
            return handover.end(Outcome.ARM_FAULT, self.arm.fault)
        if hold is not None:
            hold.gripper.check()  # a gripper fault ends the trial and stops the arm (run's finally)
        measured = self.arm.read_pose()
        last = self._latest_valid(t)
        age = t - (last.t if last is not None else 0.0)
        if age > cfg.staleness_limit_s:
            return handover.end(Outcome.TRACKER_LOST,
                                f"no valid hand sample for {age:.3f} s (staleness_limit_s = "
                                f"{cfg.staleness_limit_s})" + self._hand_refusal())
        row = next_row()
        row[SLICES["t"]] = t
        row[SLICES["measured"]] = measured
        joints = self.arm.read_joints()
        if joints is not None:
            row[SLICES["q"]] = joints
        row[SLICES["lateness_s"]] = lateness
        if last is not None:
            self._steer(handover, t, row, last, measured)
        code = self._cycle_table.sample_code(handover.stage)
        row[SLICES["stage"]] = np.nan if code is None else code
        previous, handover.measured = handover.measured, measured
        speed = 0.0 if previous is None else norm(measured - previous) / self.clock.period
        if self._steps[handover.stage](handover, t, speed, row):
            return True
        if handover.hold_at is None and t >= cfg.timeout_s:
            return True  # the outcome it started with: timeout
        row[SLICES["compute_s"]] = time.perf_counter() - began
        return False

    def _steer(self, handover: Handover, t: float, row: np.ndarray, last: HandSample,
               measured: np.ndarray) -> None:
        """Coupling (8–10) → DMP step (1–5) → safety limiter → arm, and the arrivals at H."""
        if not handover.steering:
            self.coupling.reset(last.position)
            handover.steering = True
        x = self.dmp.step(self.clock.period, self.coupling.update(last.position))
        commanded, flags = self.limiter.limit(x)
        self.arm.command(commanded)
        if handover.first_target is None:
            handover.first_target = t
            self._enter(handover, Stage.REACH, t)
        self._record(row, last, commanded, flags)
        goal, cfg = self.dmp.goal, self.config
        if handover.robot_arrival is None and norm(measured - goal) < cfg.robot_arrival_tolerance_m:
            handover.robot_arrival = t
        if handover.hand_arrival is None and norm(last.position - goal) < cfg.hand_arrival_tolerance_m:
            handover.hand_arrival = last.t

    def _enter(self, handover: Handover, stage: str, t: float) -> None:
        handover.stage = stage
        self.on_stage(stage, t)

    # -- the streamed stages' steps (one per control cycle; True: the handover ended) ------------
    def _going(self, handover: Handover, t: float, speed: float, row: np.ndarray) -> bool:
        """go: streaming, no hand sample steered by yet (the first target begins the reach)."""
        return False

    def _reaching(self, handover: Handover, t: float, speed: float, row: np.ndarray) -> bool:
        """reach: without a hold phase the handover is complete once robot and hand are at H and
        the robot is still; with one, the hold begins once the robot is at H and still."""
        hold = self.hold
        if hold is None:
            if handover.robot_arrival is not None and handover.hand_arrival is not None \
                    and speed < SETTLE_SPEED:
                return handover.end(Outcome.COMPLETED)
            return False
        if handover.robot_arrival is None or speed >= hold.settle_speed:
            return False
        handover.hold_at = t
        hold.release.reset()
        self._enter(handover, Stage.HOLD, t)
        return self._holding(handover, t, speed, row)

    def _holding(self, handover: Handover, t: float, speed: float, row: np.ndarray) -> bool:
        """hold: the release armed on the force; the pull opens the gripper (release), or none
        within ``timeout_s`` of holding ends the handover not_taken."""
        hold, force = self._held(row)
        if hold.release.update(force, in_handover=True):
            hold.gripper.open()
            handover.release_at = t
            self._enter(handover, Stage.RELEASE, t)
            self._pulled(handover, hold, row)
            return self._lingered(handover, hold, t)
        self._pulled(handover, hold, row)
        assert handover.hold_at is not None, "set as the hold began"
        if t - handover.hold_at < hold.timeout_s:
            return False
        self.on_stage(Stage.NOT_TAKEN, t)
        return handover.end(Outcome.NOT_TAKEN,
                            f"no pull above {hold.release.config.threshold_n} N within "
                            f"[release] timeout_s = {hold.timeout_s} s of holding")

    def _releasing(self, handover: Handover, t: float, speed: float, row: np.ndarray) -> bool:
        """release: the gripper is open; the arm keeps still for ``linger_s``."""
        hold, _ = self._held(row)
        self._pulled(handover, hold, row)
        return self._lingered(handover, hold, t)

    def _held(self, row: np.ndarray) -> tuple[HoldPhase, np.ndarray]:
        """The hold phase, and this cycle's force (read into the row)."""
        hold = self.hold
        assert hold is not None, "the hold and release stages exist only with a hold phase"
        force = hold.read_force()
        row[SLICES["force"]] = force
        return hold, force

    @staticmethod
    def _pulled(handover: Handover, hold: HoldPhase, row: np.ndarray) -> None:
        """The filtered pull into the row, once the baseline is taken."""
        if hold.release.baseline is not None:
            row[SLICES["pull"]] = hold.release.pull
            handover.peak_pull = max(handover.peak_pull, hold.release.pull)

    @staticmethod
    def _lingered(handover: Handover, hold: HoldPhase, t: float) -> bool:
        """Complete ``linger_s`` after the gripper opened."""
        assert handover.release_at is not None, "after the release"
        return t - handover.release_at >= hold.linger_s and handover.end(Outcome.COMPLETED)

    def _hand_refusal(self) -> str:
        """What a tracked hand (robot_io.hands.tracked_hand) refused during this trial, said in the
        trial's reason when it is lost ('' for none, or a source that refuses nothing)."""
        refused = getattr(self.hand, "invalid", 0) - self._refused_before
        if not refused:
            return ""
        return f"; {refused} samples refused, the latest as {getattr(self.hand, 'refusal', None)}"

    def _latest_valid(self, t: float) -> HandSample | None:
        """The newest valid hand sample; a new invalid one (NaN) is counted and ignored."""
        sample = self.hand.latest(t)
        if sample is not None and sample.t > self._seen_t:
            self._seen_t = sample.t
            if sample.is_valid():
                self._last = sample
            else:
                self._invalid += 1
        return self._last

    def _record(self, row: np.ndarray, hand: HandSample, commanded: np.ndarray, flags) -> None:
        dmp = self.dmp
        row[SLICES["s"]], row[SLICES["tau"]] = dmp.s, dmp.tau
        row[SLICES["x"]], row[SLICES["xd"]], row[SLICES["c_s"]] = dmp.x, dmp.xd, dmp.c_s
        row[SLICES["hand"]], row[SLICES["hand_t"]] = hand.position, hand.t
        row[SLICES["commanded"]] = commanded
        row[SLICES["limited"]] = flags.acceleration + 2 * flags.speed + 4 * flags.workspace
        coupling = self._signals
        if coupling is not None:
            row[SLICES["d"]], row[SLICES["d_filtered"]] = coupling.d, coupling.d_filtered
            row[SLICES["d_rate"]], row[SLICES["c_t"]] = coupling.d_rate, coupling.c_t
            row[SLICES["sigma_d"]], row[SLICES["sigma_j"]] = coupling.sigma_d, coupling.sigma_j

    def _halt(self) -> float | None:
        """Stop the arm (never raises) and wait, at most STOP_CONFIRM_S, until it is at rest."""
        stop_at = self.clock.now()
        try:
            self.arm.stop()
            for _ in range(int(STOP_CONFIRM_S / self.clock.period)):
                if not self.arm.is_moving:
                    break
                self.clock.wait_next_cycle()
            else:
                log.error("arm still moving %.1f s after stop()", STOP_CONFIRM_S)
        except Exception:
            log.critical("stopping the arm failed", exc_info=True)
        return stop_at

    def _summarise(self, samples: dict[str, np.ndarray], handover: Handover, misses: int,
                   stop_at: float | None) -> TrialSummary:
        cfg, dt = self.config, self.clock.period
        measured = samples["measured"]
        speeds = np.linalg.norm(np.diff(measured, axis=0), axis=1) / dt if len(measured) > 1 else [0]
        compute = samples["compute_s"][np.isfinite(samples["compute_s"])] * 1e6
        tau = samples["tau"][np.isfinite(samples["tau"])]
        robot_arrival, hand_arrival = handover.robot_arrival, handover.hand_arrival
        gap = None if robot_arrival is None or hand_arrival is None else robot_arrival - hand_arrival
        return TrialSummary(
            outcome=handover.outcome, reason=handover.reason, rate_hz=cfg.rate_hz,
            realtime=bool(getattr(self.clock, "realtime", False)),
            cycles=len(samples["t"]), duration_s=float(samples["t"][-1]) if len(samples["t"]) else 0.0,
            robot_arrival_s=robot_arrival, hand_arrival_s=hand_arrival, arrival_gap_s=gap,
            peak_speed_mps=float(np.nanmax(speeds)) if len(speeds) else 0.0,
            max_tau=float(tau.max()) if len(tau) else self.dmp.constants.tau0,
            deadline_misses=int(misses),
            limited_cycles=int(np.count_nonzero(np.nan_to_num(samples["limited"]))),
            invalid_hand_samples=self._invalid,
            compute_us_median=float(np.median(compute)) if len(compute) else 0.0,
            compute_us_p99=float(np.percentile(compute, 99)) if len(compute) else 0.0,
            last_hand_sample_s=None if self._last is None else self._last.t,
            stop_commanded_s=stop_at, first_target_s=handover.first_target, hold_s=handover.hold_at,
            release_s=handover.release_at,
            peak_pull_n=None if handover.hold_at is None else handover.peak_pull,
        )
