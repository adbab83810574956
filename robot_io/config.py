"""Controller configuration: pydantic models with documented defaults, loadable from one TOML file.

Every default that comes from the paper says so (Table I); the others are this project's choices for a
table-top UR5 handover and are documented in ``docs/controller.md``. Positions are in metres in the
robot base frame.

No value is infinite or NaN, and every limit that guards a person has a hard upper bound
(``docs/hardware.md``, "Hard bounds of the configuration"): the box lies within a UR5's reach, the
speed and acceleration caps stay at or below what the arm and the mock are strict about, and every
time-out is finite. A value outside its bound is refused with its field, its value and the range
(the bounded field types: ``robot_io.bounds``). ``[hand_source]``, ``[arm]`` and ``[gripper]`` have
one table per kind of device, each with its own keys and defaults (``robot_io.kinds``; the kinds:
``robot_io.hands.config``, ``robot_io.arms.kinds``, ``robot_io.grippers.kinds``).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from robot_io.arms.kinds import ArmConfig
from robot_io.arms.mock_arm import MockArmKind
from robot_io.arms.ur_config import URConfig
from robot_io.bounds import (
    Frozen,
    Positive,
    in_range,
)
from robot_io.clock import PrioritySetting
from robot_io.errors import ConfigError
from robot_io.grippers.gripper import NoGripperKind
from robot_io.grippers.kinds import GripperConfig
from robot_io.hands.config import HandSourceConfig, SimulatedSource
from robot_io.hands.profile import HandProfile
from robot_io.scene import SafetyLimits, SceneConfig
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

    arm: ArmConfig = MockArmKind()
    cycle: CycleConfig = CycleConfig()
    dmp: DMPConstants = DMPConstants()
    scene: SceneConfig = SceneConfig()
    safety: SafetyLimits = SafetyLimits()
    hand: HandProfile = HandProfile()
    loop: LoopConfig = LoopConfig()
    ur: URConfig = URConfig()
    hand_source: HandSourceConfig = SimulatedSource()
    gripper: GripperConfig = NoGripperKind()
    release: ReleaseConfig = ReleaseConfig()

    @model_validator(mode="after")
    def _devices_complete(self) -> ControllerConfig:
        """Device tables that cannot work are refused when the file is read, before anything is
        written or opened. A device's address is never assumed: on a lab network another robot may
        sit at any address, so a UR without ``[ur] host`` is refused, naming the key."""
        self.gripper.complete(self.arm, self.controller_host)
        self.arm.complete(self)
        return self

    @property
    def controller_host(self) -> str | None:
        """The UR controller's address (``[ur] host``), through which a tool output or a Robotiq's
        URCap is driven; None: none is set."""
        return self.ur.host

    @property
    def gripper_host(self) -> str | None:
        """Where the gripper is driven from: a Robotiq's URCap at ``[gripper] host``, else the arm's
        controller."""
        return self.gripper.address(self.controller_host)

    @model_validator(mode="after")
    def _scene_in_workspace(self) -> ControllerConfig:
        for name in ("robot_start", "handover_point"):
            point = self.scene.point(name)
            if not self.safety.contains(point):
                raise ConfigError(
                    f"scene.{name} = {written(point)} is outside the workspace box "
                    f"[{written(self.safety.workspace_min)}, {written(self.safety.workspace_max)}]")
        return self
