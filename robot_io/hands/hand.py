"""Hand samples and the interface every hand source (simulated, LSL, UDP, NatNet, Vicon) implements."""

from __future__ import annotations

import math
from typing import NamedTuple, Protocol

import numpy as np

from robot_io.vector import all_finite


class HandSample(NamedTuple):
    """One tracked hand position: ``t`` in seconds since the trial's Go, ``position`` in metres in the
    robot base frame. Kept a plain tuple: it is read every control cycle."""

    t: float
    position: np.ndarray

    def is_valid(self) -> bool:
        """A sample with a non-finite time or coordinate is discarded by the control loop."""
        return math.isfinite(self.t) and all_finite(self.position)


class HandSource(Protocol):
    """A source of hand samples. ``latest(now)`` returns the newest sample available at trial time
    ``now`` (seconds since Go), or None if there has been none yet."""

    def latest(self, now: float) -> HandSample | None: ...
