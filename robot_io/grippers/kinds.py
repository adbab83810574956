"""The kinds of ``[gripper] kind``, each registered once in :data:`GRIPPERS`: how the rig opens it
(connected; a Robotiq also activated if it was not), how the devices' report names it, and how
``handover check-devices`` checks it without moving it or switching anything."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

from robot_io.config import ControllerConfig
from robot_io.grippers.gripper import Gripper, NoGripper, ToolOutputGripper
from robot_io.grippers.robotiq import ACTIVATED, RobotiqSocketGripper, probe


class GripperKind(NamedTuple):
    """One kind of gripper: ``open`` it, ``describe`` it, ``check`` it (one line, after "gripper: ";
    it may raise RobotIOError)."""

    open: Callable[[ControllerConfig], Gripper]
    describe: Callable[[ControllerConfig], str]
    check: Callable[[ControllerConfig], str]


def _ur_host(config: ControllerConfig) -> str:
    """The UR a tool-output gripper is on: ControllerConfig refuses the kind without arm.kind = "ur",
    and that without [ur] host."""
    assert config.ur.host is not None, "[ur] host is set for a tool-output gripper"
    return config.ur.host


def _robotiq_host(config: ControllerConfig) -> str:
    """The URCap's address: ControllerConfig refuses a robotiq_socket gripper without one."""
    assert config.gripper_host is not None, "[gripper] host or [ur] host is set for a Robotiq gripper"
    return config.gripper_host


def _check_tool_output(config: ControllerConfig) -> str:
    ToolOutputGripper(_ur_host(config), config.gripper).disconnect()
    return f"tool digital output {config.gripper.tool_output} reachable (not switched)"


def _check_robotiq(config: ControllerConfig) -> str:
    """Reachable, and its activation, position and fault code (read, never activated or moved)."""
    status = probe(_robotiq_host(config), config.gripper)
    where = f"Robotiq URCap on {config.gripper_host}:{config.gripper.port}, {status.describe()}"
    if status.flt:
        return f"NOT OK — {where}: clear the fault on the teach pendant"
    if status.sta != ACTIVATED:
        return f"{where}; not moved: it activates when the rig opens it (the fingers open and close once)"
    return f"{where} (not moved)"


#: Every kind of gripper, by ``[gripper] kind``.
GRIPPERS: dict[str, GripperKind] = {
    "none": GripperKind(lambda config: NoGripper(), lambda config: "no gripper",
                        lambda config: "none configured"),
    "tool_output": GripperKind(
        lambda config: ToolOutputGripper(_ur_host(config), config.gripper),
        lambda config: f"tool digital output {config.gripper.tool_output}", _check_tool_output),
    "robotiq_socket": GripperKind(
        lambda config: RobotiqSocketGripper(_robotiq_host(config), config.gripper),
        lambda config: f"Robotiq 2F-85 on {config.gripper_host}:{config.gripper.port}", _check_robotiq),
}
