"""A non-finite value from the controller, or one computed for it, is an arm fault that moves nothing:
the UR backend against the stand-in controller with ur_rtde's real client, the safety limiter and the
mock arm."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.ur import MOVEL, SERVOL, commands, settled_servo_targets, standin
from support.waiting import wait_for

from robot_io.arms.arm import ArmState
from robot_io.arms.mock_arm import MockArm
from robot_io.arms.ur_arm import URArm
from robot_io.clock import SimClock
from robot_io.config import ControllerConfig, SafetyLimits
from robot_io.control.safety import SafetyLimiter
from robot_io.errors import ArmFault

pytestmark = pytest.mark.standin  # the stand-in UR in real time (tests/conftest.py)

NAN_POSE = [math.nan, 0.1, 0.3, 0.0, 3.14, 0.0]


def _receive_nan_pose(control, arm: URArm) -> None:
    """Make the stand-in report a NaN TCP position; wait until ur_rtde's receive side has it."""
    control("set_pose", pose=NAN_POSE)
    wait_for(lambda: math.isnan(arm._receive.getActualTCPPose()[0]), "the NaN pose at ur_rtde",
             seen=arm._receive.getActualTCPPose)


def _arm(host: str) -> URArm:
    """A URArm on ``host`` whose watchdog waits 100 s for a target: these tests send targets one by
    one from a test at normal priority, and on a loaded machine the first can come later than the
    default 0.1 s after setWatchdog (the script would stop first; the watchdog is not tested here)."""
    config = ControllerConfig()
    return URArm(config.ur.model_copy(update={"host": host, "watchdog_hz": 0.01}), config.safety)


def test_a_nan_tcp_position_faults_the_ur_arm_and_no_movel_is_sent():
    with standin() as ur:
        control, arm = ur.control, _arm(ur.host)
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
    with standin() as ur:
        control, arm = ur.control, _arm(ur.host)
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
            sent = [xyz for _, xyz in settled_servo_targets(control, arm, expected=1)]
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
