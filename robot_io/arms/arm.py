"""The arm interface that the mock arm and the UR5 backend implement (Cartesian TCP position), and the
base of every ``[arm] kind``'s model (:class:`ArmKind`; the kinds: robot_io.arms.kinds.ARMS)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from enum import StrEnum
from typing import ClassVar, Protocol

import numpy as np

from robot_io.arms.ur_config import URConfig
from robot_io.clock import Clock
from robot_io.errors import ConfigError, RobotIOError
from robot_io.kinds import DeviceKind
from robot_io.scene import SafetyLimits


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


class RecoverableArm(Arm, Protocol):
    """An arm that recovers from a fault when the experimenter asks (moving nothing)."""

    @property
    def safety_stopped(self) -> bool:
        """A protective or emergency stop: someone inspects its cause before :meth:`recover`."""

    def recover(self) -> None: ...


class ConnectedArm(RecoverableArm, Protocol):
    """A real arm, connected once per rig process: its rate, its controller's version."""

    rate_hz: int
    #: How often a recovery found the arm's link down and connected it again (links of the same
    #: server, a tool-output gripper's, dropped with it).
    links_restored: int

    @property
    def version(self) -> str | None:
        """Its controller's software version (stored with the session), None: unknown."""

    def describe(self) -> str:
        """The arm in a few words: "UR at 192.168.1.10, PolyScope 5.11, 500 Hz"."""

    def close(self) -> None: ...


class Backstop(Protocol):
    """A way to stop the arm that does not need the rig process (the rig hangs or died)."""

    def stop(self) -> None: ...

    def close(self) -> None: ...


class ArmSettings(Protocol):
    """What an arm kind reads of the controller's configuration besides its own ``[arm]`` table."""

    @property
    def ur(self) -> URConfig: ...

    @property
    def safety(self) -> SafetyLimits: ...


#: The force at the TCP a simulated arm feels, from its position and speed (the simulated pull).
ForceOf = Callable[[np.ndarray, float], np.ndarray]


class ArmKind(DeviceKind):
    """``[arm]``: which arm the rig drives. A simulated kind is made anew each trial on the trial's
    clock (:meth:`trial_arm`); any other is connected once per rig process (:meth:`connect`)."""

    #: Its controller drives tool digital outputs (``[gripper] kind = "tool_output"``).
    tool_outputs: ClassVar[bool] = False
    #: The fastest control rate it may run at, known only once connected [Hz]; None: [loop] rate_hz.
    fastest_rate_hz: ClassVar[int | None] = None

    def complete(self, settings: ArmSettings) -> None:
        """Refuse (ConfigError), when the file is read, a configuration this arm cannot run with."""

    def connect(self, settings: ArmSettings) -> ConnectedArm:
        """The arm, connected (it moves nothing)."""
        raise ConfigError(f'[arm] kind = "{self.kind}" is simulated: it has nothing to connect to')

    def trial_arm(self, clock: Clock, start: np.ndarray, force: ForceOf) -> RecoverableArm:
        """A simulated arm for one trial, at ``start`` on the trial's ``clock``."""
        raise ConfigError(f'[arm] kind = "{self.kind}" is a real arm: it is connected, not simulated')

    def describe(self, arm: ConnectedArm | None, rate_hz: int) -> str:
        """The arm in the devices' report."""
        return arm.describe() if arm is not None else f"{self.kind} arm, {rate_hz} Hz"

    def backstop(self, settings: ArmSettings) -> Backstop | None:
        """Its controller's own stop, for when the rig does not answer (None: it has none)."""
        return None

    def check(self, settings: ArmSettings) -> tuple[list[str], bool]:
        """``handover check-devices``: its lines ("arm: …"), and whether it is usable. A real arm is
        connected, its TCP, state and fault read, and closed: nothing moves."""
        if self.simulated:
            return [f'arm: {self.kind} arm ([arm] kind = "{self.kind}": no robot configured)'], True
        try:
            arm = self.connect(settings)
        except RobotIOError as exc:
            return [f"arm: NOT OK — {exc}"], True  # said NOT OK in the line
        try:
            pose, state = arm.read_pose(), arm.state
            lines = [f"arm: {arm.describe()}, TCP at {np.round(pose, 3).tolist()} m, {state.value}"
                     + (f" — {arm.fault}" if arm.fault else "")]
            if not settings.safety.contains(pose):
                lines.append("arm: WARNING — the TCP is outside the workspace box; jog it inside")
            return lines, arm.fault is None
        finally:
            arm.close()
