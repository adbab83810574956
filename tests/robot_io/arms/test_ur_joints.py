"""The UR backend reads the joint angles (``actual_q``) with ur_rtde's real client from the stand-in
controller, whose joint angles follow its TCP: the UR5's forward kinematics of what is read is the TCP
pose read, at rest and after a move; a pose no UR5 can take has no joint angles and faults nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.ur import standin
from support.waiting import wait_for

from robot_io.arms.arm import ArmState
from robot_io.arms.ur_arm import URArm
from robot_io.arms.ur_kinematics import forward, pose_to_transform
from robot_io.config import ControllerConfig

pytestmark = pytest.mark.standin  # the stand-in UR in real time (tests/conftest.py)


def _fk_matches_the_tcp(arm: URArm) -> np.ndarray:
    """The joint angles read with the TCP position; asserts that their FK is that TCP pose."""
    position = arm.read_pose()
    q = arm.read_joints()
    tcp = forward(q)
    assert np.linalg.norm(tcp[:3, 3] - position) < 1e-6
    assert np.abs(tcp[:3, :3] - pose_to_transform([0, 0, 0, *arm.orientation])[:3, :3]).max() < 1e-6
    return q


def test_the_joint_angles_read_are_the_ur5_pose_of_the_tcp_and_move_with_it():
    config = ControllerConfig()
    with standin() as ur:
        control = ur.control
        arm = URArm(config.ur.model_copy(update={"host": ur.host}), config.safety)
        try:
            start = _fk_matches_the_tcp(arm)
            assert np.allclose(control("state")["q"], start)
            arm.move_to(arm.read_pose() + np.array([0.10, 0.15, -0.05]))
            moved = _fk_matches_the_tcp(arm)
            assert 0.05 < np.abs(moved - start).max() < 1.0  # moved, on the same branch
            control("set_pose", pose=[0.95, 0.6, 0.05, 0.0, math.pi, 0.0])  # beyond the UR5's reach
            wait_for(lambda: arm.read_pose()[0] >= 0.9 and np.all(np.isnan(arm.read_joints())),
                     "the unreachable pose read with no joint angles",
                     seen=lambda: (arm.read_pose().tolist(), arm.read_joints().tolist()))
            assert arm.state is ArmState.IDLE  # recorded as missing, not a fault
        finally:
            arm.close()
