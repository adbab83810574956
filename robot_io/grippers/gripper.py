"""The gripper interface (open/close) and its tool-digital-output implementation (``RTDEIOInterface``).

Most UR-mounted parallel grippers without their own URCap (pneumatic, or electric with a digital
input) are driven by one tool digital output; ``open_level`` says which level opens. A Robotiq 2F-85
on its URCap's socket is :class:`robot_io.grippers.robotiq.RobotiqSocketGripper`.
"""

from __future__ import annotations

import logging
from typing import Literal, Protocol

from pydantic import Field

from robot_io.arms.arm import ArmKind
from robot_io.arms.kinds import ARMS
from robot_io.errors import ConfigError, GripperFault, RobotIOError
from robot_io.kinds import DeviceKind

log = logging.getLogger(__name__)


class Gripper(Protocol):
    @property
    def holding(self) -> bool:
        """Closed on the object (as last commanded)."""

    def open(self) -> None:
        """Open; called in the control loop, so it must not wait for the fingers."""

    def close(self) -> None:
        """Close on the object (in prepare, the arm still: it may wait for the fingers)."""

    def check(self) -> None:
        """Raise :class:`~robot_io.errors.GripperFault` if the gripper reported one (called every
        control cycle while the cycle runs: no I/O)."""

    def disconnect(self) -> None: ...


class NoGripper:
    """``[gripper] kind = "none"``: nothing to switch; only remembers what it was told, so the cycle
    and the simulated participant's pull see the same open/closed state as with a real gripper."""

    def __init__(self) -> None:
        self.holding = False

    def open(self) -> None:
        self.holding = False

    def close(self) -> None:
        self.holding = True

    def check(self) -> None:
        pass

    def disconnect(self) -> None:
        pass


class ToolOutputGripper:
    """Drives tool digital output ``config.tool_output`` of the UR at ``host``."""

    def __init__(self, host: str, config: ToolOutputKind) -> None:
        import rtde_io

        self.config, self.host = config, host
        self.holding = False
        try:
            self._io = rtde_io.RTDEIOInterface(host)
        except RuntimeError as exc:
            raise RobotIOError(f"gripper: cannot connect the RTDE IO interface to {host}: {exc}") from exc

    def _set(self, level: bool, what: str) -> None:
        """Switch the output; a link that is down is a :class:`GripperFault` (the trial ends and the
        arm stops), never an error that ends the rig (ur_rtde raises RuntimeError: Broken pipe)."""
        try:
            switched = self._io.setToolDigitalOut(self.config.tool_output, level)
        except RuntimeError as exc:
            raise GripperFault(f"gripper: the RTDE link of tool digital output "
                               f"{self.config.tool_output} is down ({exc}); Recover arm connects "
                               "it again") from exc
        if not switched:
            raise RobotIOError(f"gripper: setting tool digital output {self.config.tool_output} "
                               f"to {level} ({what}) failed")
        log.info("gripper %s (tool digital output %d = %s)", what, self.config.tool_output, level)

    def reconnect(self) -> None:
        """Connect the RTDE IO link again: it goes through the UR's RTDE server, so whatever drops
        the arm's link (a cable, a switch, a controller reboot) drops this one too, and only a write
        would notice it (a write into a half-closed socket may even seem to work)."""
        try:  # reconnect() alone: ur_rtde 1.6's disconnect() of a dropped link raises (EOF)
            self._io.reconnect()
        except RuntimeError as exc:
            raise GripperFault(f"gripper: cannot connect the RTDE IO interface to {self.host} "
                               f"again: {exc}") from exc

    def open(self) -> None:
        self._set(self.config.open_level, "open")
        self.holding = False

    def close(self) -> None:
        self._set(not self.config.open_level, "close")
        self.holding = True

    def check(self) -> None:
        """A tool output reports nothing back: a failed switch raised already."""

    def disconnect(self) -> None:
        self._io.disconnect()


class GripperKind(DeviceKind):
    """``[gripper]``: the gripper that holds the object, one model per kind (robot_io.grippers.kinds
    .GRIPPERS). ``controller``: the address of the arm's controller (its tool outputs, its URCap),
    None: the arm has none."""

    def complete(self, arm: ArmKind, controller: str | None) -> None:
        """Refuse (ConfigError), when the file is read, a gripper that cannot work on ``arm``."""

    def address(self, controller: str | None) -> str | None:
        """Where the gripper is driven from."""
        return controller

    def open(self, controller: str | None) -> Gripper:
        """The gripper, connected (a Robotiq one also activated, if it was not)."""
        raise NotImplementedError

    def describe(self, controller: str | None) -> str:
        """The gripper in the devices' report."""
        raise NotImplementedError

    def check(self, controller: str | None) -> str:
        """``handover check-devices``: one line (after "gripper: "), switching and moving nothing;
        it may raise RobotIOError."""
        raise NotImplementedError

    def _at(self, controller: str | None) -> str:
        """:meth:`address`, which :meth:`complete` made sure of."""
        address = self.address(controller)
        assert address is not None, f"ControllerConfig refuses a {self.kind} gripper without an address"
        return address


class NoGripperKind(GripperKind):
    """``[gripper] kind = "none"``: nothing to switch (:class:`NoGripper`)."""

    simulated = True

    kind: Literal["none"] = "none"

    def open(self, controller: str | None) -> NoGripper:
        return NoGripper()

    def describe(self, controller: str | None) -> str:
        return "no gripper"

    def check(self, controller: str | None) -> str:
        return "none configured"


class ToolOutputKind(GripperKind):
    """``[gripper] kind = "tool_output"``: a tool digital output of the arm's controller drives it
    (:class:`ToolOutputGripper`)."""

    kind: Literal["tool_output"]
    tool_output: int = Field(0, ge=0, le=1, description="the tool digital output that drives it")
    open_level: bool = Field(True, description="the output level that opens the gripper")

    def complete(self, arm: ArmKind, controller: str | None) -> None:
        if not arm.tool_outputs:
            kinds = " or ".join(repr(kind) for kind, model in ARMS.items() if model.tool_outputs)
            raise ConfigError(f"gripper.kind = 'tool_output' needs arm.kind = {kinds} (the output is "
                              f"the arm controller's), not {arm.kind!r}")

    def open(self, controller: str | None) -> ToolOutputGripper:
        return ToolOutputGripper(self._at(controller), self)

    def describe(self, controller: str | None) -> str:
        return f"tool digital output {self.tool_output}"

    def check(self, controller: str | None) -> str:
        ToolOutputGripper(self._at(controller), self).disconnect()
        return f"tool digital output {self.tool_output} reachable (not switched)"

