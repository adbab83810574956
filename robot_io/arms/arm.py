"""The arm interface that the mock arm and the UR5 backend implement (Cartesian TCP position)."""

from __future__ import annotations

import threading
from enum import StrEnum
from typing import Protocol

import numpy as np


class ArmState(StrEnum):
    IDLE = "idle"  # not streaming; may be moved to a start pose
    STREAMING = "streaming"  # accepting one servo target per cycle
    STOPPING = "stopping"  # stop requested, decelerating
    STOPPED = "stopped"  # at rest after a stop; begin_stream() to go on
    FAULT = "fault"  # protective stop or other fault; see ``fault``


class Arm(Protocol):
    """What the control loop needs of an arm."""

    @property
    def state(self) -> ArmState: ...

    @property
    def fault(self) -> str | None:
        """Why the arm is in FAULT, in plain words; None otherwise."""

    def move_to(self, pose: np.ndarray, stop: threading.Event | None = None) -> None:
        """Bounded move to a start pose before or after a trial (not streamed); a ``stop`` set
        meanwhile halts it and raises MoveStopped."""

    def begin_stream(self) -> None:
        """Prepare to take servo targets; raises ArmFault if the arm cannot."""

    def command(self, target: np.ndarray) -> None:
        """One servo target for this cycle; raises ArmFault if the arm is not streaming."""

    def read_pose(self) -> np.ndarray:
        """The measured TCP position."""

    def read_joints(self) -> np.ndarray | None:
        """The measured joint angles [rad] of the state the last :meth:`read_pose` read, or None
        for an arm that does not report them."""

    def read_force(self) -> np.ndarray:
        """The force at the TCP [N], base frame (the participant's pull while holding)."""

    def stop(self) -> None:
        """Halt now. Must work in any state, and never raise."""

    @property
    def is_moving(self) -> bool: ...
