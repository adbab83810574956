"""The stand-in's controller state: registers, safety, the running program and a bounded arm model.

All of it is guarded by one lock (``Controller.lock``), held by the server threads while they read or
write registers and by the tick thread while it advances the model one controller cycle.

The arm is a bounded first-order follower: each cycle the TCP moves towards the current servo target
with time constant ``lookahead_time`` of the last ``servoL``, its speed capped at ``max_speed``. A
``moveL`` goes in a straight line at its speed and acceleration; a stop decelerates at the given rate.
Orientation is carried, not modelled.

The TCP pose is in the robot base frame with no tool offset (TCP = flange), as the controller reports
it (there is no base or world offset: the lab configuration's positions are in the base frame too).
The joint angles ``actual_q`` follow it through the UR5's analytic inverse kinematics
(:mod:`robot_io.arms.ur_kinematics`), each time the solution nearest the previous one (from
:data:`READY_Q` at start), so they move continuously and FK(q) is the reported pose. A pose no UR5
can take (out of reach, or not finite after ``set_pose``) has no joint angles: NaN.

A Robotiq 2F-85 on its URCap's socket is modelled in :mod:`robot_io.standins.urcap`.

The measured force is what the test sets (``set_force``) — no contact model — unless a rehearsal
configured the simulated participant's pull (``configure_pull``, :mod:`robot_io.hands.simulated_pull`):
then each cycle it is the pull of the hand last reported with ``set_hand`` on the object the TCP
holds.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from robot_io.arms.ur_kinematics import nearest_inverse
from robot_io.hands.simulated_pull import SimulatedPull
from robot_io.standins.ur.rtde_protocol import FORMATS, OUTPUT_TYPES
from robot_io.standins.urcap import RobotiqModel

log = logging.getLogger(__name__)

#: Input registers that carry the control script's command id (lower and upper register range).
COMMAND_REGISTERS = {"input_int_register_0": 0, "input_int_register_24": 24}


class Series(IntEnum):
    """Controller major version: CB-series (125 Hz) or e-Series (500 Hz)."""

    CB3 = 3
    E_SERIES = 5

    @property
    def rate_hz(self) -> int:
        return 125 if self is Series.CB3 else 500

    @property
    def version(self) -> tuple[int, int, int, int]:
        return (3, 15, 7, 106331) if self is Series.CB3 else (5, 11, 1, 108318)


class Safety(IntEnum):
    """``safety_mode`` values of the RTDE interface."""

    NORMAL = 1
    PROTECTIVE_STOP = 3
    ROBOT_EMERGENCY_STOP = 7


#: Bits of ``safety_status_bits``.
SAFETY_BIT = {Safety.NORMAL: 0, Safety.PROTECTIVE_STOP: 2, Safety.ROBOT_EMERGENCY_STOP: 6}
EMERGENCY_STOPPED_BIT = 7
#: Bits of ``robot_status_bits``: power on, program running.
POWER_ON_BIT, PROGRAM_RUNNING_BIT = 0, 1
#: The dashboard refuses to unlock a protective stop within this many seconds of it.
UNLOCK_DELAY_S = 5.0
#: The joint angles the stand-in's first inverse kinematics starts from [rad]: the usual UR "ready"
#: pose (0, −π/2, π/2, −π/2, −π/2, 0) turned to face +x, where the table-top scene is: elbow up,
#: tool pointing down (the TCP at (0.487, 0.109, 0.432) m).
READY_Q = (np.pi, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0)


@dataclass
class Arm:
    """TCP pose [x, y, z, rx, ry, rz] and linear velocity of the modelled arm, and the UR5 joint
    angles of that pose (:meth:`joints`)."""

    pose: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    max_speed: float = 1.5
    q: np.ndarray = field(default_factory=lambda: np.array(READY_Q))
    _q_pose: np.ndarray | None = field(default=None, init=False, repr=False)  # the pose of q

    def joints(self) -> np.ndarray:
        """The joint angles of the current pose [rad]: the inverse-kinematics solution nearest the
        last one (computed once per pose); NaN for a pose no UR5 can take."""
        if self._q_pose is None or not np.array_equal(self._q_pose, self.pose):
            previous = self.q if np.all(np.isfinite(self.q)) else np.array(READY_Q)
            q = nearest_inverse(self.pose, previous) if np.all(np.isfinite(self.pose)) else None
            self.q = np.full(6, np.nan) if q is None else q
            self._q_pose = self.pose.copy()
        return self.q

    def follow(self, target: np.ndarray, time_constant: float, dt: float) -> None:
        """First-order step towards ``target`` (time constant ≥ dt), speed-capped."""
        wanted = (target[:3] - self.pose[:3]) / max(time_constant, dt)
        self._move(wanted, dt)
        self.pose[3:] = target[3:]

    def approach(self, target: np.ndarray, speed: float, acceleration: float, dt: float) -> bool:
        """One step of a straight-line move; True once at the target."""
        offset = target[:3] - self.pose[:3]
        distance = float(np.linalg.norm(offset))
        if distance < 1e-6:
            self.pose[:3] = target[:3]
            self.velocity = np.zeros(3)
            return True
        current = float(np.linalg.norm(self.velocity))
        step_speed = min(speed, current + acceleration * dt, np.sqrt(2 * acceleration * distance))
        self._move(offset / distance * max(step_speed, acceleration * dt), dt, limit=distance)
        return False

    def decelerate(self, deceleration: float, dt: float) -> bool:
        """One step of a stop; True once at rest."""
        speed = float(np.linalg.norm(self.velocity))
        if speed == 0.0:
            return True
        self._move(self.velocity * max(0.0, speed - deceleration * dt) / speed, dt)
        return False

    def halt(self) -> None:
        self.velocity = np.zeros(3)

    def _move(self, velocity: np.ndarray, dt: float, limit: float = np.inf) -> None:
        speed = float(np.linalg.norm(velocity))
        if speed > self.max_speed:
            velocity = velocity * (self.max_speed / speed)
            speed = self.max_speed
        if speed * dt > limit:
            velocity = velocity * (limit / (speed * dt))
        self.pose[:3] = self.pose[:3] + velocity * dt
        self.velocity = velocity


@dataclass
class Received:
    """One command data package as the controller received it: monotonic time, command id, doubles."""

    t: float
    command: int
    values: list[float]


def _zero(name: str) -> object:
    """An output variable the stand-in does not model: zero (a vector of zeros) of its type."""
    fmt = FORMATS[OUTPUT_TYPES[name]]
    return [0] * int(fmt[0]) if fmt[0].isdigit() else 0


class Controller:
    """Registers, safety state, program state, the arm and the log of received commands."""

    def __init__(self, series: Series, start_pose: np.ndarray) -> None:
        self.series = series
        self.period = 1.0 / series.rate_hz
        self.lock = threading.RLock()
        self.inputs: dict[str, object] = {}
        self.input_times: dict[str, float] = {}
        self.outputs: dict[str, object] = {}
        self.arm = Arm(np.asarray(start_pose, dtype=float).copy())
        self.force = np.zeros(6)
        self.safety = Safety.NORMAL
        self.safety_since = 0.0
        self.program = None  # a running program (robot_io.standins.ur.control_script.ControlScript)
        self.tool_outputs = 0
        self.robotiq = RobotiqModel()  # the 2F-85 behind the URCap socket (port 63352)
        self.received: list[Received] = []
        self.events: list[str] = []
        self.last_script = ""
        self.stalled_until = 0.0
        #: How late the clients that only read (no input recipe) get each output package [s]
        self.reader_lag_s = 0.0
        #: The longest time between two cycles [s] (injected stalls aside): this machine's load on
        #: a stand-in, which a real controller's hardware does not have.
        self.longest_gap_s = 0.0
        self.time = 0.0
        # the rehearsal's simulated participant: where their hand is, and their pull once holding
        self.hand: np.ndarray | None = None
        self.pull: SimulatedPull | None = None
        self.pull_output, self.pull_open_level = 0, True
        self.pull_gripper = "tool_output"  # or "robotiq_socket": which gripper holds the object

    # -- what the RTDE outputs report ------------------------------------------------------------
    def output_values(self, names: list[str]) -> list[object]:
        """The values of an output recipe's ``names`` this cycle. The controller's state is read
        once per package: building it for every name (a recipe has dozens) took a quarter of a core
        at 125 Hz, more than the rest of the stand-in."""
        state: dict[str, object] | None = None
        values = []
        for name in names:
            if name in self.outputs:
                values.append(self.outputs[name])
            elif name in self.inputs:
                values.append(self.inputs[name])
            else:
                state = self._state() if state is None else state
                values.append(state[name] if name in state else _zero(name))
        return values

    def _state(self) -> dict[str, object]:
        """The output variables the stand-in models, as the controller reports them now."""
        return {
            "timestamp": self.time, "actual_TCP_pose": list(self.arm.pose),
            "actual_q": list(self.arm.joints()),
            "target_TCP_pose": list(self.arm.pose), "actual_TCP_force": list(self.force),
            "actual_TCP_speed": [*self.arm.velocity, 0.0, 0.0, 0.0],
            "target_TCP_speed": [*self.arm.velocity, 0.0, 0.0, 0.0],
            "robot_mode": 7, "safety_mode": int(self.safety), "safety_status": int(self.safety),
            "robot_status_bits": self.robot_status_bits, "safety_status_bits": self.safety_status_bits,
            "runtime_state": 2 if self.program is not None else 1,
            "actual_digital_output_bits": self.tool_outputs << 16, "speed_scaling": 1.0,
            "target_speed_fraction": 1.0, "tcp_force_scalar": float(np.linalg.norm(self.force[:3])),
        }

    @property
    def robot_status_bits(self) -> int:
        return (1 << POWER_ON_BIT) | ((self.program is not None) << PROGRAM_RUNNING_BIT)

    @property
    def safety_status_bits(self) -> int:
        bits = 1 << SAFETY_BIT[self.safety]
        if self.safety is Safety.ROBOT_EMERGENCY_STOP:
            bits |= 1 << EMERGENCY_STOPPED_BIT
        return bits

    # -- inputs ------------------------------------------------------------------------------------
    def _scalar(self, name: str) -> float:
        """An input that is one number (a register or a mask; other inputs may be vectors)."""
        value = self.inputs[name]
        assert isinstance(value, int | float), f"{name} is a scalar input, not {value!r}"
        return float(value)

    def write_inputs(self, names: list[str], values: list[object]) -> None:
        """Apply one input data package (called by the RTDE server with the lock held)."""
        now = time.monotonic()
        for name, value in zip(names, values, strict=True):
            self.inputs[name] = value
            self.input_times[name] = now
        if "tool_digital_output_mask" in names:
            mask = int(self._scalar("tool_digital_output_mask"))
            bits = int(self._scalar("tool_digital_output")) if "tool_digital_output" in self.inputs else 0
            self.tool_outputs = (self.tool_outputs & ~mask) | (bits & mask)
            self.event(f"tool digital outputs = {self.tool_outputs:#04b}")
        for register, offset in COMMAND_REGISTERS.items():
            if register in names and int(self._scalar(register)) != 0:
                doubles = [self._scalar(f"input_double_register_{i + offset}")
                           for i in range(48 - offset) if f"input_double_register_{i + offset}" in names]
                self.received.append(Received(now, int(self._scalar(register)), doubles))

    # -- safety ------------------------------------------------------------------------------------
    def protective_stop(self, reason: str) -> None:
        self._stop_all(Safety.PROTECTIVE_STOP, reason)

    def emergency_stop(self, reason: str) -> None:
        self._stop_all(Safety.ROBOT_EMERGENCY_STOP, reason)

    def _stop_all(self, safety: Safety, reason: str) -> None:
        self.safety, self.safety_since = safety, time.monotonic()
        self.arm.halt()
        self.end_program(f"{safety.name.lower()}: {reason}")

    def unlock_protective_stop(self) -> str:
        """The dashboard's reply to ``unlock protective stop``."""
        if self.safety is not Safety.PROTECTIVE_STOP:
            return "Protective stop releasing"  # what a controller says when there is nothing to do
        if time.monotonic() - self.safety_since < UNLOCK_DELAY_S:
            return ("Cannot unlock protective stop until 5s after occurrence. "
                    "Always inspect cause of protective stop before unlocking")
        self.safety = Safety.NORMAL
        self.event("protective stop unlocked")
        return "Protective stop releasing"

    def release_emergency_stop(self) -> None:
        if self.safety is Safety.ROBOT_EMERGENCY_STOP:
            self.safety = Safety.NORMAL
            self.event("emergency stop released")

    # -- programs ----------------------------------------------------------------------------------
    def start_program(self, program) -> None:
        if self.program is not None:
            self.end_program("replaced by a new program")
        if self.safety is not Safety.NORMAL:
            self.event(f"program {program.name} refused: {self.safety.name}")
            return
        self.program = program
        self.event(f"program {program.name} started")

    def end_program(self, why: str) -> None:
        if self.program is not None:
            self.event(f"program {self.program.name} ended: {why}")
            self.program = None

    def event(self, text: str) -> None:
        log.info("stand-in: %s", text)
        self.events.append(text)

    # -- one controller cycle ----------------------------------------------------------------------
    @property
    def holding(self) -> bool:
        """The gripper holds the object: the Robotiq's fingers stopped on it, or the gripper on the
        pull's tool output is closed (its level is not the opening one)."""
        if self.pull_gripper == "robotiq_socket":
            return self.robotiq.holding
        return bool(self.tool_outputs >> self.pull_output & 1) != self.pull_open_level

    def tick(self) -> None:
        self.time += self.period
        self.robotiq.tick(self.period, self.event)
        if self.pull is not None:
            self.force[:3] = self.pull.force(self.time, self.hand, self.arm.pose[:3], self.holding,
                                             float(np.linalg.norm(self.arm.velocity)))
        if self.program is not None:
            if not self.program.step(self, self.period):
                self.end_program("finished")
        elif self.safety is Safety.NORMAL:
            self.arm.decelerate(10.0, self.period)
