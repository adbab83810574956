"""The Robotiq gripper against a stand-in's URCap socket: its configuration, its stand-in state and
waiting for the fault the gripper's worker finds."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from robot_io.errors import GripperFault
from robot_io.grippers.robotiq import RobotiqSocketGripper, RobotiqSocketKind
from support.ur import Standin
from support.waiting import wait_for


def robotiq_config(host: str, **gripper) -> RobotiqSocketKind:
    """``[gripper] kind = "robotiq_socket"`` at ``host`` (``gripper``: other [gripper] settings)."""
    return RobotiqSocketKind(kind="robotiq_socket", host=host, **gripper)


@contextlib.contextmanager
def connected_gripper(ur: Standin, **gripper) -> Iterator[RobotiqSocketGripper]:
    """A gripper connected (and activated) on ``ur``'s URCap socket; disconnected afterwards."""
    connected = RobotiqSocketGripper(ur.host, robotiq_config(ur.host, **gripper))
    try:
        yield connected
    finally:
        connected.disconnect()


def robotiq_state(ur: Standin) -> dict:
    """The stand-in's 2F-85: registers, finger position, object, fault, answering."""
    return ur.control("state")["robotiq"]


def fault_of(gripper: RobotiqSocketGripper) -> GripperFault | None:
    try:
        gripper.check()
    except GripperFault as exc:
        return exc
    return None


def await_fault(gripper: RobotiqSocketGripper, ur: Standin, what: str) -> GripperFault:
    """The fault the gripper's worker reports, once it has; ``what`` names the awaited fault."""
    return wait_for(lambda: fault_of(gripper), what, seen=lambda: robotiq_state(ur))
