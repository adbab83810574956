"""The gripper interface (open/close) and its tool-digital-output implementation (``RTDEIOInterface``).

Most UR-mounted parallel grippers without their own URCap (pneumatic, or electric with a digital
input) are driven by one tool digital output; ``open_level`` says which level opens. A Robotiq 2F-85
on its URCap's socket is :class:`robot_io.grippers.robotiq.RobotiqSocketGripper`.
"""

from __future__ import annotations

import logging
from typing import Protocol

from robot_io.config import GripperConfig
from robot_io.errors import GripperFault, RobotIOError

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

    def __init__(self, host: str, config: GripperConfig) -> None:
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
