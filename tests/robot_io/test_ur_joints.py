"""The UR backend reads the joint angles (``actual_q``) with ur_rtde's real client from the stand-in
controller, whose joint angles follow its TCP: the UR5's forward kinematics of what is read is the TCP
pose read, at rest and after a move; a pose no UR5 can take has no joint angles and faults nothing."""

from __future__ import annotations

import math
import time

import numpy as np
from ur_helpers import standin

from robot_io.arm import ArmState
from robot_io.config import ControllerConfig
from robot_io.ur_arm import URArm
from robot_io.ur_kinematics import forward, pose_to_transform

HOST = "127.0.0.171"


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
    with standin(HOST) as control:
        arm = URArm(config.ur.model_copy(update={"host": HOST}), config.safety)
        try:
            start = _fk_matches_the_tcp(arm)
            assert np.allclose(control("state")["q"], start)
            arm.move_to(arm.read_pose() + np.array([0.10, 0.15, -0.05]))
            moved = _fk_matches_the_tcp(arm)
            assert 0.05 < np.abs(moved - start).max() < 1.0  # moved, on the same branch
            control("set_pose", pose=[0.95, 0.6, 0.05, 0.0, math.pi, 0.0])  # beyond the UR5's reach
            deadline = time.monotonic() + 2.0
            while arm.read_pose()[0] < 0.9 or not np.all(np.isnan(arm.read_joints())):
                assert time.monotonic() < deadline, "the stand-in still reports joint angles"
                time.sleep(0.005)
            assert arm.state is ArmState.IDLE  # recorded as missing, not a fault
        finally:
            arm.close()
