"""The learned coupling parameters θ = (a, δ, k) and their box (Table I, "Optimized").

``a`` and ``δ`` are the steepness and offset of σ_j in eq. (10); ``k = k_t = k_s`` is the coupling gain
of eqs. (8)–(9). The paper's tables label the first two a_d and δ_d. k = 0.01 is the non-reactive robot.
"""

from __future__ import annotations

import math
from typing import ClassVar

from pydantic import BaseModel, ConfigDict, field_validator

from robot_io.errors import ConfigError

#: Table I, "Optimized (Θ)": the box the learner searches and the controller accepts.
THETA_BOUNDS: dict[str, tuple[float, float]] = {
    "a": (1.0, 10.0),
    "delta": (-1.0, 1.0),
    "k": (0.01, 15.0),
}


def check_range(field: str, value: float, low: float, high: float) -> float:
    """Return ``value`` if it is finite and within [low, high]; else raise ConfigError naming all three."""
    if not math.isfinite(value) or not low <= value <= high:
        raise ConfigError(f"{field} = {value!r} is outside the allowed range [{low}, {high}]")
    return value


class Theta(BaseModel):
    """One point of the parameter space Θ (Table I). Out of range is an error, never a silent clip."""

    model_config = ConfigDict(frozen=True)

    NAMES: ClassVar[tuple[str, ...]] = tuple(THETA_BOUNDS)

    a: float
    delta: float
    k: float

    @field_validator("a", "delta", "k", mode="after")
    @classmethod
    def _within_box(cls, value: float, info) -> float:
        low, high = THETA_BOUNDS[info.field_name]
        return check_range(f"theta.{info.field_name}", value, low, high)

    @classmethod
    def parse(cls, text: str) -> Theta:
        """Parse ``"A,DELTA,K"`` as given on the command line."""
        parts = [p.strip() for p in text.split(",")]
        if len(parts) != 3:
            raise ConfigError(f"theta = {text!r} must be three numbers 'a,delta,k'")
        try:
            a, delta, k = (float(p) for p in parts)
        except ValueError as exc:
            raise ConfigError(f"theta = {text!r} must be three numbers 'a,delta,k'") from exc
        return cls(a=a, delta=delta, k=k)

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.a, self.delta, self.k)
