"""A kinematic Cartesian TCP standing in for the arm: speed and acceleration limits, one-cycle latency.

A target commanded at cycle n is reached at the next cycle, when the arm is next read or commanded,
having taken one nominal period to get there (as ``servoL(..., time=period)`` does on a UR), however
late or early the next cycle comes: timing jitter of the loop does not turn into speed spikes.

The mock is strict: a target that would need more than its speed or acceleration limit is not smoothed
over but trips a fault, as a following error trips a real controller's protective stop; so a stream
that the safety limiter let through is checked again here, and a non-finite target or start pose
faults it as it faults the UR backend. ``stop()`` decelerates at
``stop_deceleration`` on the loop's clock until at rest, the same on simulated and real time.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Literal

import numpy as np

from robot_io.arms.arm import ArmKind, ArmState, ForceOf
from robot_io.clock import Clock
from robot_io.errors import ArmFault
from robot_io.vector import all_finite, norm

log = logging.getLogger(__name__)


class MockArm:
    def __init__(self, clock: Clock, start: np.ndarray, max_speed: float = 1.5,
                 max_acceleration: float = 10.0, stop_deceleration: float = 10.0,
                 force: Callable[[np.ndarray, float], np.ndarray] | None = None) -> None:
        self.clock = clock
        self._force = force
        self.max_speed = max_speed
        self.max_acceleration = max_acceleration
        self.stop_deceleration = stop_deceleration
        self.position = np.asarray(start, dtype=float).copy()
        self.velocity = np.zeros(3)
        self.period = clock.period
        self._target: np.ndarray | None = None
        self._target_time = 0.0
        self._time = 0.0
        self._state = ArmState.IDLE
        self._fault: str | None = None
        self.stop_requested_at: float | None = None
        self.commands_received = 0

    @property
    def state(self) -> ArmState:
        return self._state

    @property
    def fault(self) -> str | None:
        return self._fault

    @property
    def is_moving(self) -> bool:
        self._advance()
        return bool(self.velocity.any())

    def move_to(self, pose: np.ndarray, stop: threading.Event | None = None) -> None:
        """The mock places the TCP at ``pose`` at once (a real arm does a bounded moveL, which
        ``stop`` can halt)."""
        if self._state in (ArmState.STREAMING, ArmState.STOPPING):
            raise ArmFault(f"move_to refused while the arm is {self._state}")
        pose = np.asarray(pose, dtype=float)
        if not all_finite(pose):
            raise ArmFault(f"move_to refused: non-finite start pose {pose.tolist()}")
        self.position = pose.copy()
        self.velocity = np.zeros(3)

    def begin_stream(self) -> None:
        if self._state is ArmState.FAULT:
            raise ArmFault(f"arm in fault: {self._fault}")
        if self.is_moving:
            raise ArmFault("arm still moving; wait until it is at rest")
        self._time = self.clock.now()
        self._target = None
        self.stop_requested_at = None
        self._state = ArmState.STREAMING

    def command(self, target: np.ndarray) -> None:
        self._advance()
        if self._state is not ArmState.STREAMING:
            raise ArmFault(f"servo target refused: arm is {self._state}"
                           + (f" ({self._fault})" if self._fault else ""))
        target = np.asarray(target, dtype=float)
        if not all_finite(target):
            self._trip(f"non-finite servo target {target.tolist()}; not taken")
            raise ArmFault(self._fault)
        self._target = target.copy()
        self._target_time = self._time
        self.commands_received += 1

    def read_pose(self) -> np.ndarray:
        self._advance()
        return self.position.copy()

    def read_joints(self) -> None:
        """The mock models the TCP only: it has no joint angles."""
        return None

    def read_force(self) -> np.ndarray:
        """The force on the TCP [N]: what ``force(position, speed)`` says (the simulated
        participant's pull), zero without it."""
        position = self.read_pose()
        if self._force is None:
            return np.zeros(3)
        return np.asarray(self._force(position, norm(self.velocity)), dtype=float)

    def stop(self) -> None:
        self._advance()
        if self.stop_requested_at is None:
            self.stop_requested_at = self.clock.now()
        self._target = None
        if self._state is not ArmState.FAULT:
            self._state = ArmState.STOPPING

    def inject_fault(self, reason: str) -> None:
        """Test hook: a protective stop. The arm halts where it is and refuses targets."""
        self._advance()
        self._trip(reason)

    @property
    def safety_stopped(self) -> bool:
        """Every mock fault stands for a protective stop: inspect before :meth:`recover`."""
        return self._state is ArmState.FAULT

    def recover(self) -> None:
        """Clear the fault (the experimenter has inspected its cause); moves nothing."""
        self._fault = None
        self._state = ArmState.IDLE

    def _advance(self) -> None:
        now = self.clock.now()
        dt = now - self._time
        if dt <= 0:
            return
        self._time = now
        if self._state is ArmState.STOPPING:
            self._decelerate(dt)
        elif self._target is not None and now > self._target_time:
            self._track(self._target)

    def _track(self, target: np.ndarray) -> None:
        """Reach the pending ``target`` in one nominal period."""
        dt = self.period
        velocity = (target - self.position) / dt
        speed = norm(velocity)
        acceleration = norm(velocity - self.velocity) / dt
        if speed > self.max_speed * (1 + 1e-9):
            self._trip(f"following error: target needs {speed:.3f} m/s "
                       f"(max_speed = {self.max_speed} m/s)")
        elif acceleration > self.max_acceleration * (1 + 1e-9):
            self._trip(f"following error: target needs {acceleration:.2f} m/s² "
                       f"(max_acceleration = {self.max_acceleration} m/s²)")
        else:
            self.position = target
            self.velocity = velocity
            self._target = None

    def _trip(self, reason: str) -> None:
        log.error("mock arm fault: %s", reason)
        self._fault = reason
        self._state = ArmState.FAULT
        self._target = None
        self.velocity = np.zeros(3)

    def _decelerate(self, dt: float) -> None:
        speed = norm(self.velocity)
        new_speed = max(0.0, speed - self.stop_deceleration * dt)
        if speed > 0:
            mean = 0.5 * (speed + new_speed)
            direction = self.velocity / speed
            self.position = self.position + direction * mean * dt
            self.velocity = direction * new_speed
        if new_speed == 0.0:
            self.velocity = np.zeros(3)
            self._state = ArmState.STOPPED


class MockArmKind(ArmKind):
    """``[arm] kind = "mock"``: the kinematic mock arm, no hardware; its force is the simulated
    participant's pull."""

    simulated = True

    kind: Literal["mock"] = "mock"

    def trial_arm(self, clock: Clock, start: np.ndarray, force: ForceOf) -> MockArm:
        return MockArm(clock, start, force=force)
