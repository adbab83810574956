"""The whole handover cycle (robot_io.control.cycle) on the mock arm and the simulated hand, on simulated
time: stages in order, the release fired by the participant's pull and armed only in the hold, a fresh
baseline each trial, the k_ext compliance while grasped, not_taken, stop, a gripper fault and the
ready check."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from robot_io.arms.mock_arm import MockArm
from robot_io.clock import SimClock
from robot_io.config import ControllerConfig
from robot_io.control.cycle import CycleDevices, Gates, run_cycle
from robot_io.control.loop import Outcome
from robot_io.control.stages import PAPER_CYCLE, Stage
from robot_io.errors import GripperFault
from robot_io.grippers.gripper import NoGripper
from robot_io.hands.hand import HandSample
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.hands.simulated_pull import SimulatedPull
from robot_io.theta import Theta

THETA = Theta(a=5.0, delta=-0.2, k=5.0)


def devices(config: ControllerConfig, bias: np.ndarray | None = None, seed: int = 3,
            gripper: NoGripper | None = None):
    """Mock arm whose force is the simulated participant's pull (plus a constant ``bias``, as a
    CB-series force estimate has), the simulated hand, no gripper hardware (or ``gripper``)."""
    clock = SimClock(config.loop.rate_hz)
    hand = SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, config.hand, seed)
    gripper = gripper or NoGripper()
    scene = config.scene
    pull = SimulatedPull(scene.point("hand_start") - scene.point("handover_point"),
                         config.hand.pull_n, config.hand.grasp_delay_s)
    offset = np.zeros(3) if bias is None else bias

    def force(tcp: np.ndarray, speed: float) -> np.ndarray:
        now = clock.now()
        return pull.force(now, hand.latest(now).position, tcp, gripper.holding, speed) + offset

    arm = MockArm(clock, scene.point("robot_start") + 0.05, force=force)
    return CycleDevices(arm=arm, hand=hand, gripper=gripper, clock=clock)


def run(config: ControllerConfig, rig: CycleDevices, gates: Gates | None = None):
    stages: list[tuple[Stage, float]] = []
    record = run_cycle(config, THETA, rig, gates or Gates.automatic(),
                       lambda stage, t: stages.append((stage, t)))
    return record, stages


def test_a_completed_cycle_goes_through_every_stage_and_releases_on_the_pull():
    config = ControllerConfig()
    rig = devices(config)
    record, stages = run(config, rig)
    s = record.summary
    assert [stage for stage, _ in stages] == [
        Stage.PREPARE, Stage.LOADED, Stage.READY, Stage.GO, Stage.REACH, Stage.HOLD, Stage.RELEASE,
        Stage.RETRACT, Stage.DONE]
    assert s.outcome is Outcome.COMPLETED
    assert 0 < s.robot_arrival_s <= s.hold_s < s.release_s < s.retract_end_s
    # the grasp delay passed before anyone pulled, and the pull passed the threshold
    assert s.release_s - max(s.hold_s, s.hand_arrival_s) >= config.hand.grasp_delay_s
    assert s.peak_pull_n >= config.release.threshold_n
    assert not rig.gripper.holding  # opened
    np.testing.assert_allclose(rig.arm.read_pose(), config.scene.point("robot_start"))  # back at R
    samples = record.samples
    stage, pull = samples["stage"], samples["pull"]
    assert np.all(np.isnan(pull[stage == 1]))  # armed only in the hold: nothing during the reach
    released = np.flatnonzero(stage == 3)[0]
    assert pull[released - 1] >= config.release.threshold_n > np.nanmax(pull[: released - 1])


def test_the_baseline_is_taken_fresh_so_a_biased_force_does_not_release_by_itself():
    config = ControllerConfig()
    biased, _ = run(config, devices(config, bias=np.array([4.0, -3.0, 25.0])))
    plain, _ = run(config, devices(config))
    # a 25 N bias is above the 10 N threshold: only the baseline keeps it from releasing at once
    assert biased.summary.outcome is Outcome.COMPLETED
    assert biased.summary.release_s == pytest.approx(plain.summary.release_s, abs=0.01)


def test_while_grasped_the_k_ext_term_lets_the_arm_yield_towards_the_pull():
    config = ControllerConfig()
    record, _ = run(config, devices(config))
    samples, goal = record.samples, config.scene.point("handover_point")
    direction = config.scene.point("hand_start") - goal
    direction /= np.linalg.norm(direction)
    hold = samples["stage"] == 2
    yielded = (samples["x"][hold] - goal) @ direction
    armed = np.isfinite(samples["pull"][hold])
    # eq. (1) with k_ext F: no yield before the baseline is armed, then along the pull
    assert np.max(np.abs(yielded[~armed])) < 2e-3
    assert yielded[-1] > 5e-3 and yielded[-1] == pytest.approx(yielded[armed].max())


def test_no_pull_within_the_release_timeout_ends_the_trial_not_taken_and_the_robot_keeps_it():
    config = ControllerConfig.model_validate({"hand": {"pull_n": 0.0},
                                              "release": {"timeout_s": 1.5}})
    rig = devices(config)
    record, stages = run(config, rig)
    s = record.summary
    assert s.outcome is Outcome.NOT_TAKEN and s.release_s is None
    assert s.duration_s == pytest.approx(s.hold_s + 1.5, abs=0.01)
    assert [stage for stage, _ in stages][-3:] == [Stage.NOT_TAKEN, Stage.RETRACT, Stage.DONE]
    assert rig.gripper.holding  # still holding the object, back at R
    np.testing.assert_allclose(rig.arm.read_pose(), config.scene.point("robot_start"))


class FaultingGripper(NoGripper):
    """A gripper that reports :attr:`fault` once it is set (as the Robotiq's worker does)."""

    fault: GripperFault | None = None

    def check(self) -> None:
        if self.fault is not None:
            raise self.fault

    def close(self) -> None:
        self.check()  # a URCap that does not answer fails the close as it fails a check
        super().close()


def test_a_gripper_fault_in_the_hold_ends_the_trial_stops_the_arm_and_nothing_retracts():
    config = ControllerConfig()
    gripper = FaultingGripper()
    rig = devices(config, gripper=gripper)
    stages: list[Stage] = []

    def on_stage(stage: Stage, t: float) -> None:
        stages.append(stage)
        if stage == Stage.HOLD:
            gripper.fault = GripperFault("gripper: the object was lost while holding")

    record = run_cycle(config, THETA, rig, Gates.automatic(), on_stage)
    assert record.summary.outcome is Outcome.GRIPPER_FAULT
    assert record.summary.reason == "gripper: the object was lost while holding"
    assert stages[-1] == Stage.HOLD  # no release, no retract: the arm stays where it stopped
    assert rig.arm.stop_requested_at is not None and not rig.arm.is_moving


def test_a_gripper_that_fails_to_close_at_r_ends_the_trial_as_a_gripper_fault_before_go():
    """The runner locks Start on a gripper fault as on an arm fault (app/session/supervisor.py), so the
    cycle tells it apart from any other error, at R as in the hold."""
    config = ControllerConfig()
    gripper = FaultingGripper()
    gripper.fault = GripperFault("gripper: the Robotiq URCap did not answer 'GET OBJ'")
    rig = devices(config, gripper=gripper)
    stages: list[Stage] = []
    record = run_cycle(config, THETA, rig, Gates.automatic(), lambda stage, t: stages.append(stage))
    assert record.summary.outcome is Outcome.GRIPPER_FAULT
    assert record.summary.reason == "prepare: gripper: the Robotiq URCap did not answer 'GET OBJ'"
    assert stages == [Stage.PREPARE] and not gripper.holding


def test_stop_while_waiting_for_go_ends_the_trial_before_anything_streams():
    config = ControllerConfig()
    rig = devices(config)
    gates = Gates.of(PAPER_CYCLE)
    assert gates.confirm(Stage.PREPARE)  # Object loaded; Go never comes
    threading.Timer(0.05, gates.stop.request, ["the experimenter's Stop"]).start()
    record, stages = run(config, rig, gates)
    assert record.summary.outcome is Outcome.STOPPED and record.summary.cycles == 0
    assert record.summary.reason == "the experimenter's Stop"  # the request's own reason
    assert Stage.GO not in [stage for stage, _ in stages]


class FarHand:
    """A tracker that sees the hand 40 cm from the start A."""

    def __init__(self, config: ControllerConfig) -> None:
        self.position = config.scene.point("hand_start") + np.array([0.0, 0.4, 0.0])

    def latest(self, now: float) -> HandSample:
        return HandSample(now, self.position)


def test_ready_waits_for_the_hand_in_the_start_zone_and_says_why():
    config = ControllerConfig.model_validate({"cycle": {"ready_timeout_s": 0.2}})
    rig = devices(config)
    rig.hand = FarHand(config)
    reasons: list[str | None] = []
    record = run_cycle(config, THETA, rig, Gates.automatic(), lambda stage, t: None,
                       on_waiting=reasons.append)
    assert record.summary.outcome is Outcome.TRACKER_LOST
    assert "0.40 m from the start A" in reasons[0] and "start_zone_m = 0.15" in reasons[0]
    assert "ready_timeout_s = 0.2" in record.summary.reason
