"""The bounded field types of the configuration (``robot_io.config`` and each device's table): a
finite number in its range, a workspace or scene point, a rotation row, and the frozen model every
table is. A value outside its bound is refused with its field, its value and the range
(``docs/hardware.md``, "Hard bounds of the configuration")."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Annotated, Any

from annotated_types import GroupedMetadata
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

Positive = Annotated[float, Field(gt=0)]

#: A UR5's reach from the base axis [m] (Universal Robots' data sheet: 850 mm) ...
UR5_REACH_M = 0.85
#: ... plus a gripper and the object it holds: no workspace coordinate is farther from the base.
WORKSPACE_BOUND_M = 1.0
#: TCP speed cap bound [m/s]: what the mock arm and the stand-in controller are strict about, above
#: any handover reach (the DMP peaks well under 1 m/s) and far below the arm's own capability; near a
#: person, ISO/TS 15066 asks for the lowest speed that does the task, not the most the arm can do.
MAX_SPEED_BOUND = 1.5
#: TCP acceleration cap bound [m/s²]: the mock's strict limit and the largest stop deceleration.
MAX_ACCELERATION_BOUND = 10.0


@dataclass(frozen=True)
class in_range(GroupedMetadata):  # noqa: N801 (written in the field's type: `Annotated[float, in_range(0, 1)]`)
    """A finite float in (low, high] (``low_open``) or [low, high]. A value outside, ``inf`` or NaN
    is refused with the range in the message (pydantic adds the field and the value).

    Pydantic unpacks it into a validator that says the range and the bounds of the JSON schema.
    """

    low: float
    high: float
    unit: str = ""
    low_open: bool = field(default=True, kw_only=True)

    def __iter__(self) -> Iterator[object]:
        low, high, low_open = self.low, self.high, self.low_open
        bracket = "(" if low_open else "["
        allowed = f"must be a finite number in {bracket}{low:g}, {high:g}]" + (
            f" {self.unit}" if self.unit else "")

        def check(value: Any) -> Any:
            try:
                number = float(value)
            except (TypeError, ValueError):
                return value  # not a number at all: pydantic's own message says so
            if not (math.isfinite(number) and (number > low if low_open else number >= low)
                    and number <= high):
                raise ValueError(allowed)
            return number

        yield BeforeValidator(check)
        yield Field(gt=low, le=high) if low_open else Field(ge=low, le=high)


Coordinate = Annotated[float, in_range(-WORKSPACE_BOUND_M, WORKSPACE_BOUND_M, "m", low_open=False)]
WorkspaceCorner = tuple[Coordinate, Coordinate, Coordinate]
#: A point of the table-top scene (the participant's side reaches beyond the robot's) [m].
SceneCoordinate = Annotated[float, in_range(-3.0, 3.0, "m", low_open=False)]
ScenePoint = tuple[SceneCoordinate, SceneCoordinate, SceneCoordinate]
#: One row of the tracker → robot rotation matrix (each entry of a rotation is within ±1).
RotationEntry = Annotated[float, in_range(-1.0, 1.0, low_open=False)]
RotationRow = tuple[RotationEntry, RotationEntry, RotationEntry]
#: How far a configured rotation may be from orthonormal (largest entry of |RᵀR − I|):
#: `handover calibrate-tracker` prints its entries to 6 decimals, a few 1e-6 off.
ROTATION_TOLERANCE = 1e-3


class Frozen(BaseModel):
    """A configuration table: read-only, no unknown key, no infinite or NaN value."""

    # allow_inf_nan=False: no configuration value is infinite or NaN, bounded or not.
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


