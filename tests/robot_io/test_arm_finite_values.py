"""A non-finite value from the controller, or one computed for it, is an arm fault that moves nothing:
the UR backend against the stand-in controller with ur_rtde's real client, the safety limiter and the
mock arm."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from ur_helpers import MOVEL, SERVOL, commands, settled_servo_targets, standin

from robot_io.arm import ArmState
from robot_io.clock import SimClock
from robot_io.config import ControllerConfig, SafetyLimits
from robot_io.errors import ArmFault
from robot_io.mock_arm import MockArm
from robot_io.safety import SafetyLimiter
from robot_io.ur_arm import URArm

NAN_POSE = [math.nan, 0.1, 0.3, 0.0, 3.14, 0.0]


def _receive_nan_pose(control, arm: URArm) -> None:
    """Make the stand-in report a NaN TCP position; wait until ur_rtde's receive side has it."""
    control("set_pose", pose=NAN_POSE)
    while not math.isnan(arm._receive.getActualTCPPose()[0]):
        time.sleep(0.002)


def _arm(host: str) -> URArm:
    config = ControllerConfig()
    return URArm(config.ur.model_copy(update={"host": host}), config.safety)


def test_a_nan_tcp_position_faults_the_ur_arm_and_no_movel_is_sent():
    with standin("127.0.0.151") as control:
        arm = _arm("127.0.0.151")
        try:
            start = arm.read_pose()
            _receive_nan_pose(control, arm)
            with pytest.raises(ArmFault, match="non-finite TCP position"):
                arm.move_to(start)  # a legal start pose, 0 m from where the arm was
            assert arm.state is ArmState.FAULT
            assert "non-finite TCP position" in arm.fault
            with pytest.raises(ArmFault):
                arm.begin_stream()
        finally:
            arm.close()
        assert MOVEL not in commands(control) and SERVOL not in commands(control)


def test_a_nan_tcp_position_while_streaming_stops_the_stream():
    with standin("127.0.0.152") as control:
        arm = _arm("127.0.0.152")
        try:
            arm.begin_stream()
            start = arm.read_pose()
            arm.command(start + np.array([0.0002, 0.0, 0.0]))
            _receive_nan_pose(control, arm)
            with pytest.raises(ArmFault, match="non-finite TCP position"):
                arm.read_pose()
            assert arm.state is ArmState.FAULT
            with pytest.raises(ArmFault):
                arm.command(start)
            sent = [xyz for _, xyz in settled_servo_targets(control, expected=1)]
        finally:
            arm.close()
    assert all(xyz == pytest.approx(start + np.array([0.0002, 0.0, 0.0])) for xyz in sent)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_the_safety_limiter_refuses_a_non_finite_target(bad):
    limiter = SafetyLimiter(SafetyLimits(), 1 / 125)
    limiter.reset(np.array([0.35, -0.35, 0.35]))
    with pytest.raises(ArmFault, match="non-finite"):
        limiter.limit(np.array([0.35, bad, 0.35]))
    assert np.all(np.isfinite(limiter.position)) and np.all(limiter.velocity == 0)
    with pytest.raises(ArmFault, match="non-finite"):
        limiter.reset(np.array([bad, 0.0, 0.3]))


def test_the_mock_arm_faults_on_a_non_finite_target_or_start_pose():
    clock = SimClock(125)
    arm = MockArm(clock, np.array([0.35, -0.35, 0.35]))
    with pytest.raises(ArmFault, match="non-finite"):
        arm.move_to(np.array([math.nan, 0.0, 0.3]))
    assert np.all(np.isfinite(arm.read_pose()))
    arm.begin_stream()
    with pytest.raises(ArmFault, match="non-finite"):
        arm.command(np.array([0.35, math.inf, 0.35]))
    assert arm.state is ArmState.FAULT and np.all(np.isfinite(arm.read_pose()))
