"""The table-top of Fig. 1 (robot start R, handover point H, hand start A, box B, place C) and the
safety limits every target passes before it reaches the arm (``robot_io.control.safety``; the UR
backend checks them again). Positions are in metres in the robot base frame."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import Field, model_validator

from robot_io.bounds import (
    MAX_ACCELERATION_BOUND,
    MAX_SPEED_BOUND,
    Frozen,
    ScenePoint,
    WorkspaceCorner,
    in_range,
)
from robot_io.errors import ConfigError


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
