"""Controller configuration: pydantic models with documented defaults, loadable from one TOML file.

Every default that comes from the paper says so (Table I); the others are this project's choices for a
table-top UR5 handover and are documented in ``docs/controller.md``. Positions are in metres in the
robot base frame.

No value is infinite or NaN, and every limit that guards a person has a hard upper bound
(``docs/hardware.md``, "Hard bounds of the configuration"): the box lies within a UR5's reach, the
speed and acceleration caps stay at or below what the arm and the mock are strict about, and every
time-out is finite. A value outside its bound is refused with its field, its value and the range
(the bounded field types: ``robot_io.bounds``). ``[hand_source]`` has one table per kind of hand
source, each with its own keys and defaults (``robot_io.hands.config``).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from robot_io.bounds import (
    MAX_ACCELERATION_BOUND,
    MAX_SPEED_BOUND,
    Frozen,
    Positive,
    ScenePoint,
    WorkspaceCorner,
    in_range,
)
from robot_io.clock import PrioritySetting
from robot_io.errors import ConfigError
from robot_io.hands.config import HandSourceConfig, SimulatedSource
from robot_io.vector import written


class DMPConstants(Frozen):
    """Fixed DMP and coupling constants (Table I, "Fixed")."""

    tau0: Positive = Field(1.0, description="τ0, uncoupled time constant [s] (Table I)")
    alpha_x: Positive = Field(20.0, description="α_x of eq. (1); β_x = α_x/4 (Table I)")
    alpha_s: Positive = Field(4.0, description="α_s of the phase, eq. (3) (Table I)")
    alpha_d: Positive = Field(20.0, description="α_d of the distance filter, eq. (7) (Table I)")
    sigma_d_a: float = Field(13.0, description="a_d of the fixed σ_d, eq. (10) (Table I)")
    sigma_d_delta: float = Field(-0.35, description="δ_d of the fixed σ_d, eq. (10) (Table I)")
    k_ext: float = Field(0.8, ge=0, description="gain of the external-force term (Table I)")
    n_basis: int = Field(50, ge=2, le=500, description="Gaussian basis functions of f_nl")
    demo_fit_duration: Positive = Field(
        1.3, description="time span [s] of the demonstration used for the fit (reach + rest)")
    d0_min: Positive = Field(
        0.02, description="smallest start distance d0 [m] accepted by eq. (8) (guard against d0≈0)")

    @property
    def beta_x(self) -> float:
        """β_x = α_x/4: critically damped transformation system (Sect. III-A)."""
        return self.alpha_x / 4.0


class SceneConfig(Frozen):
    """Table-top geometry of Fig. 1: robot start R, handover point H, hand start A, box B, place C."""

    robot_start: ScenePoint = Field((0.35, -0.35, 0.35), description="R: robot TCP start [m]")
    handover_point: ScenePoint = Field((0.55, 0.05, 0.30), description="H: handover point = DMP goal g [m]")
    hand_start: ScenePoint = Field((0.95, 0.10, 0.05), description="A: hand start on the desk [m]")
    box: ScenePoint = Field((0.65, 0.25, 0.15), description="B: box, about 25 cm from H [m]")
    place: ScenePoint = Field((1.00, 0.40, 0.05), description="C: where the box is put down [m]")

    def point(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name), dtype=float)


class SafetyLimits(Frozen):
    """Limits applied to every target before it reaches the arm (see ``robot_io.control.safety``)."""

    workspace_min: WorkspaceCorner = Field(
        (0.10, -0.60, 0.05), description="workspace box, lower corner [m], each within ±1 m")
    workspace_max: WorkspaceCorner = Field(
        (0.90, 0.60, 0.80), description="workspace box, upper corner [m], each within ±1 m")
    max_speed: Annotated[float, in_range(0, MAX_SPEED_BOUND, "m/s")] = Field(
        1.0, description="TCP speed cap [m/s]")
    max_acceleration: Annotated[float, in_range(0, MAX_ACCELERATION_BOUND, "m/s²")] = Field(
        5.0, description="TCP acceleration cap [m/s²]")

    @model_validator(mode="after")
    def _box_not_empty(self) -> SafetyLimits:
        for axis, (low, high) in enumerate(zip(self.workspace_min, self.workspace_max, strict=True)):
            if low >= high:
                raise ConfigError(f"safety.workspace_min[{axis}] = {low} must be below "
                                  f"workspace_max[{axis}] = {high}")
        return self

    def contains(self, point: np.ndarray) -> bool:
        return bool(np.all(point >= self.workspace_min) and np.all(point <= self.workspace_max))


#: Upper bounds of the simulated participant's ranges: a reaction, a hand speed, a pause.
HAND_RANGE_BOUNDS = {"reaction_delay_s": 5.0, "mean_speed_mps": 3.0, "pause_s": 10.0}


#: A minimum-jerk reach's peak speed over its mean speed (15/8).
MINIMUM_JERK_PEAK_OVER_MEAN = 1.875


class HandProfile(Frozen):
    """The participant's hand: the fastest any hand moves, which tracked samples must respect, and
    how the simulated participant moves (each range drawn from uniformly per trial)."""

    max_speed: Annotated[float, in_range(0, 10, "m/s")] = Field(
        3.0, description="the fastest a hand moves [m/s]: a tracked sample farther from the last "
                         "accepted one than this speed allows is a tracker jump, refused as a "
                         "dropout (reach-to-grasp peaks at 1-1.5 m/s; 3 leaves room for a hurry)")

    tracker_rate_hz: Annotated[float, in_range(0, 2000, "Hz")] = Field(
        100.0, description="tracker sample rate (Vicon in the paper; mocap runs at most ~2 kHz)")
    reaction_delay_s: tuple[float, float] = Field((0.15, 0.35), description="delay after Go [s]")
    mean_speed_mps: tuple[float, float] = Field(
        (0.45, 0.65), description="mean hand speed of each reach [m/s] (duration = length/speed)")
    pause_s: tuple[float, float] = Field(
        (0.25, 0.50), description="pause to grasp the box at B and to put it down at C [s]")
    noise_std_m: Annotated[float, in_range(0, 0.1, "m", low_open=False)] = Field(
        0.0, description="tracker noise, std per axis [m]")
    dropout_rate: float = Field(0.0, ge=0, lt=1, description="share of tracker samples lost")
    pull_n: float = Field(15.0, ge=0, le=100, description="pull on the object once grasped [N]; 0: "
                                                         "never takes it (see robot_io.hands.simulated_pull)")
    grasp_delay_s: float = Field(0.5, ge=0, le=10, description="from touching the object to pulling "
                                                               "[s]; longer than [release] baseline_s")

    @model_validator(mode="after")
    def _ranges_ordered(self) -> HandProfile:
        for name in ("reaction_delay_s", "mean_speed_mps", "pause_s"):
            low, high = getattr(self, name)
            if not 0 <= low <= high <= HAND_RANGE_BOUNDS[name]:
                raise ConfigError(f"hand.{name} = ({low}, {high}) must satisfy 0 ≤ low ≤ high ≤ "
                                  f"{HAND_RANGE_BOUNDS[name]:g}")
        if self.mean_speed_mps[0] <= 0:
            raise ConfigError(f"hand.mean_speed_mps = {self.mean_speed_mps} must be > 0")
        peak = MINIMUM_JERK_PEAK_OVER_MEAN * self.mean_speed_mps[1]
        if peak > self.max_speed:
            raise ConfigError(f"hand.mean_speed_mps = {self.mean_speed_mps} makes reaches that peak "
                              f"at {peak:.2f} m/s, beyond hand.max_speed = {self.max_speed:g} m/s: "
                              "the simulated hand's samples would be refused as tracker jumps")
        return self


class LoopConfig(Frozen):
    """The control loop: rate, end conditions, and when the tracker counts as lost."""

    rate_hz: Literal[125, 500] = Field(500, description="control rate: 125 (CB-series) or 500 Hz")
    robot_arrival_tolerance_m: Annotated[float, in_range(0, 0.1, "m")] = Field(
        0.01, description="robot 'at H' radius [m]")
    hand_arrival_tolerance_m: Annotated[float, in_range(0, 0.2, "m")] = Field(
        0.03, description="hand 'at H' radius [m]")
    staleness_limit_s: Annotated[float, in_range(0, 0.5, "s")] = Field(
        0.1, description="a hand sample older than this means the tracker is lost: stop [s]; at "
                         "most 0.5 s, so the arm never moves long towards a person it cannot see")
    timeout_s: Annotated[float, in_range(0, 120, "s")] = Field(
        20.0, description="a trial longer than this ends as 'timeout' [s]")
    realtime_priority: PrioritySetting = Field(
        "auto", description="the rig's threads under SCHED_FIFO on the wall clock (needs root, "
                            "CAP_SYS_NICE or an rtprio limit; docs/hardware.md): \"auto\" where "
                            "the OS permits it, saying so at start where it does not; true: refuse "
                            "to start without it; false: never")


class URConfig(Frozen):
    """The UR5 over RTDE (``robot_io.arms.ur_arm``); see ``docs/hardware.md``."""

    host: str | None = Field(
        None, description="controller address, required by [arm] kind = \"ur\"; never assumed "
                          "(a stand-in: 127.0.0.x)")
    servo_lookahead_s: float = Field(
        0.1, ge=0.03, le=0.2, description="servoL lookahead time [s] (ur_rtde's range [0.03, 0.2])")
    servo_gain: float = Field(300.0, ge=100, le=2000,
                              description="servoL proportional gain (ur_rtde's range [100, 2000])")
    watchdog_hz: float = Field(
        10.0, gt=0, le=125,
        description="controller watchdog: the program stops if no target comes for 1/watchdog_hz s; "
                    "10 Hz tolerates Python jitter (50 Hz tripped on a 31 ms stall)")
    move_speed: float = Field(0.25, gt=0, le=0.5, description="moveL to the start pose: speed [m/s]")
    move_acceleration: float = Field(0.5, gt=0, le=1.2, description="moveL acceleration [m/s²]")
    max_move_distance: float = Field(
        0.6, gt=0, le=1.0, description="move_to refuses a start pose farther than this from the TCP [m]")
    stop_deceleration: float = Field(5.0, gt=0, le=10,
                                     description="servoStop deceleration at the end of a trial [m/s²]")
    connect_timeout_s: Annotated[float, in_range(0, 120, "s")] = Field(
        10.0, description="give up connecting after this [s]")
    upper_range_registers: bool = Field(
        False, description="use RTDE registers 24–47 (when a fieldbus owns 0–23)")


#: A Robotiq register value (position, speed, force): one byte.
RobotiqByte = Annotated[int, Field(ge=0, le=255)]
#: The Robotiq URCap's gripper socket on the controller (its manual, "Control over the socket").
ROBOTIQ_PORT = 63352


class GripperConfig(Frozen):
    """The gripper that holds the object: ``tool_output``, a tool digital output drives it;
    ``robotiq_socket``, a Robotiq 2F-85 through its URCap's socket (``robot_io.grippers.robotiq``)."""

    kind: Literal["none", "tool_output", "robotiq_socket"] = Field("none", description="gripper interface")
    tool_output: int = Field(0, ge=0, le=1, description="tool_output: the tool digital output that drives it")
    open_level: bool = Field(True, description="tool_output: the output level that opens the gripper")
    host: str | None = Field(
        None, description="robotiq_socket: address of the controller whose URCap drives the gripper; "
                          "unset: [ur] host (the URCap runs on the UR's controller); never assumed")
    port: int = Field(ROBOTIQ_PORT, ge=1, le=65535,
                      description="robotiq_socket: the URCap's gripper socket (63352 on every controller)")
    speed: RobotiqByte = Field(255, description="robotiq_socket: finger speed, 0 (20 mm/s) to 255 "
                                                "(150 mm/s on a 2F-85)")
    force: RobotiqByte = Field(50, description="robotiq_socket: grip force, 0 (20 N) to 255 (235 N on a "
                                               "2F-85); low enough that a pull opens no finger")
    open_position: RobotiqByte = Field(0, description="robotiq_socket: finger position that opens "
                                                      "(0: fully open, 85 mm on a 2F-85)")
    closed_position: RobotiqByte = Field(255, description="robotiq_socket: finger position commanded "
                                                          "to close (255: fully closed); the object "
                                                          "stops the fingers before it")
    move_timeout_s: Annotated[float, in_range(0, 30, "s")] = Field(
        5.0, description="robotiq_socket: a close or an open that has not ended within this long is "
                         "a fault [s] (a full 2F-85 stroke takes 0.6 s at speed 255, 4.3 s at 0)")
    reply_timeout_s: Annotated[float, in_range(0, 10, "s")] = Field(
        1.0, description="robotiq_socket: no answer from the URCap within this long is a fault [s]")

    @model_validator(mode="after")
    def _closes_past_open(self) -> GripperConfig:
        if self.closed_position <= self.open_position:
            raise ConfigError(f"gripper.closed_position = {self.closed_position} must be above "
                              f"gripper.open_position = {self.open_position} (0 open … 255 closed)")
        return self


class ReleaseConfig(Frozen):
    """Force-threshold release (docs/controller.md): baseline at grasp, filtered norm, threshold."""

    threshold_n: Annotated[float, in_range(0, 50, "N")] = Field(
        10.0, description="pull above the baseline that releases [N]")
    filter_cutoff_hz: Annotated[float, in_range(0, 50, "Hz")] = Field(
        5.0, description="first-order low-pass on the force (a CB-series estimate is ±10 N noisy); "
                         "below the Nyquist frequency of the 125 Hz CB-series rate")
    baseline_s: Annotated[float, in_range(0, 2, "s")] = Field(
        0.2, description="averaging window of the baseline at grasp [s]")
    timeout_s: Annotated[float, in_range(0, 60, "s")] = Field(
        10.0, description="no release within this long of holding: the trial ends "
                          "not_taken and the robot retracts with the object [s]")


class ArmConfig(Frozen):
    """Which arm the rig drives: the kinematic mock (no hardware) or a UR over RTDE (``[ur]``)."""

    kind: Literal["mock", "ur"] = Field("mock", description="mock: kinematic mock arm; ur: a UR5 "
                                                            "over RTDE at [ur] host (moves it!)")


class CycleConfig(Frozen):
    """The whole handover cycle around the coupled reach (docs/controller.md): prepare → ready → go →
    reach → hold → release (or not taken) → retract."""

    start_zone_m: float = Field(
        0.15, gt=0, le=0.5, description="ready: the hand must be within this radius of A [m]")
    ready_timeout_s: float = Field(
        30.0, gt=0, le=600, description="no live tracker with the hand at A within this long: the "
                                        "trial is aborted [s]")
    hold_settle_speed: float = Field(
        0.02, gt=0, le=0.2, description="hold starts when the robot is at H below this speed [m/s]")
    release_linger_s: float = Field(
        0.2, ge=0, le=2.0, description="after the release the arm keeps holding still this long, so "
                                       "the participant takes the object clear [s]")


class ControllerConfig(Frozen):
    """Everything the controller needs; the TOML file has one table per field."""

    arm: ArmConfig = ArmConfig()
    cycle: CycleConfig = CycleConfig()
    dmp: DMPConstants = DMPConstants()
    scene: SceneConfig = SceneConfig()
    safety: SafetyLimits = SafetyLimits()
    hand: HandProfile = HandProfile()
    loop: LoopConfig = LoopConfig()
    ur: URConfig = URConfig()
    hand_source: HandSourceConfig = SimulatedSource()
    gripper: GripperConfig = GripperConfig()
    release: ReleaseConfig = ReleaseConfig()

    @model_validator(mode="after")
    def _devices_complete(self) -> ControllerConfig:
        """Device tables that cannot work are refused when the file is read, before anything is
        written or opened. A device's address is never assumed: on a lab network another robot may
        sit at any address, so a UR without ``[ur] host`` is refused, naming the key."""
        if self.gripper.kind == "tool_output" and self.arm.kind != "ur":
            raise ConfigError("gripper.kind = 'tool_output' needs arm.kind = 'ur' (the output is the "
                              f"UR's), not {self.arm.kind!r}")
        if self.gripper.kind == "robotiq_socket" and self.gripper.host is None and self.ur.host is None:
            raise ConfigError('[gripper] host is not set and neither is [ur] host; [gripper] kind = '
                              '"robotiq_socket" needs the address of the controller its URCap runs '
                              'on. Set [gripper] host (or [ur] host): it has no default')
        if self.arm.kind == "ur" and self.ur.host is None:
            raise ConfigError('[ur] host is not set; [arm] kind = "ur" needs the UR controller\'s '
                              'address. Set it (e.g. host = "192.168.1.10"): it has no default, so no '
                              "robot at an assumed address is ever driven")
        return self

    @property
    def gripper_host(self) -> str | None:
        """Where a ``robotiq_socket`` gripper's URCap listens: ``[gripper] host``, else ``[ur] host``."""
        return self.gripper.host or self.ur.host

    @model_validator(mode="after")
    def _scene_in_workspace(self) -> ControllerConfig:
        for name in ("robot_start", "handover_point"):
            point = self.scene.point(name)
            if not self.safety.contains(point):
                raise ConfigError(
                    f"scene.{name} = {written(point)} is outside the workspace box "
                    f"[{written(self.safety.workspace_min)}, {written(self.safety.workspace_max)}]")
        return self
