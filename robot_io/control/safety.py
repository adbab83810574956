"""The safety limiter: the last stage before the arm. Nothing it returns leaves the workspace box,
successive targets never imply more than the speed or acceleration cap, and a non-finite target or
start position is refused (an ArmFault: the loop stops the arm), never passed on."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from robot_io.errors import ArmFault
from robot_io.scene import SafetyLimits
from robot_io.vector import all_finite, norm


class LimitFlags(NamedTuple):
    acceleration: bool
    speed: bool
    workspace: bool

    def any(self) -> bool:
        return self.acceleration or self.speed or self.workspace


class SafetyLimiter:
    """Limits a stream of targets sent every ``dt`` seconds.

    Per cycle: the velocity implied by the new target is limited in change (acceleration cap), then in
    norm (speed cap), and the resulting target is clamped into the workspace box. The limiter's own
    previous output is the reference, so the caps hold for what is actually sent.
    """

    def __init__(self, limits: SafetyLimits, dt: float) -> None:
        self.limits = limits
        self.dt = dt
        self._low = np.asarray(limits.workspace_min, dtype=float)
        self._high = np.asarray(limits.workspace_max, dtype=float)
        self.position = np.zeros(3)
        self.velocity = np.zeros(3)

    def reset(self, position: np.ndarray) -> None:
        """Start from the arm's measured position, at rest."""
        self.position = _finite(position, "start position").copy()
        self.velocity = np.zeros(3)

    def limit(self, target: np.ndarray) -> tuple[np.ndarray, LimitFlags]:
        dt = self.dt
        wanted = (_finite(target, "target") - self.position) / dt
        change = wanted - self.velocity
        max_change = self.limits.max_acceleration * dt
        change_norm = norm(change)
        accel_limited = change_norm > max_change
        velocity = self.velocity + (change * (max_change / change_norm) if accel_limited else change)
        speed = norm(velocity)
        speed_limited = speed > self.limits.max_speed
        if speed_limited:
            velocity *= self.limits.max_speed / speed
        wanted_position = self.position + velocity * dt
        position = np.minimum(np.maximum(wanted_position, self._low), self._high)  # np.clip
        box_limited = bool((position != wanted_position).any())
        self.velocity = (position - self.position) / dt
        self.position = position
        return position.copy(), LimitFlags(accel_limited, speed_limited, box_limited)


def _finite(values: np.ndarray, what: str) -> np.ndarray:
    """``values`` as floats; a NaN or infinite one would pass every ``>`` check, so it is refused."""
    array = np.asarray(values, dtype=float)
    if not all_finite(array):
        raise ArmFault(f"safety limiter: non-finite {what} {array.tolist()}; not sent")
    return array
