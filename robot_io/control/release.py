"""Force-threshold release (docs/controller.md): the gripper opens when the participant pulls.

At grasp the baseline F₀ is the mean force over ``baseline_s`` (a CB-series UR5 has no wrist sensor:
its TCP force is estimated from joint currents, biased and ±10 N noisy, so only a change counts).
Each cycle the force is low-pass filtered (first order, ``filter_cutoff_hz``, exact discretisation)
and the release fires when ‖F̃ − F₀‖ ≥ ``threshold_n`` — only in the handover state, never while the
robot is still reaching.
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np

from robot_io.config import ReleaseConfig
from robot_io.vector import norm


class ReleasePhase(StrEnum):
    IDLE = "idle"  # not yet at the handover state
    BASELINE = "baseline"  # averaging F₀
    ARMED = "armed"  # watching the pull
    RELEASED = "released"


class ForceRelease:
    """Feed :meth:`update` once per cycle with the measured force and whether the handover state holds."""

    def __init__(self, config: ReleaseConfig, dt: float) -> None:
        self.config, self.dt = config, dt
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * config.filter_cutoff_hz * dt)
        self.baseline_cycles = max(1, round(config.baseline_s / dt))
        self.reset()

    def reset(self) -> None:
        self.phase = ReleasePhase.IDLE
        self.baseline: np.ndarray | None = None
        self.filtered = np.zeros(3)
        self.pull = 0.0
        self._sum, self._count = np.zeros(3), 0

    def update(self, force: np.ndarray, in_handover: bool) -> bool:
        """True on the cycle the release fires (once)."""
        force = np.asarray(force, dtype=float)[:3]
        if self.phase is ReleasePhase.RELEASED:
            return False
        if not in_handover:
            if self.phase is not ReleasePhase.IDLE:
                self.reset()
            return False
        if self.phase is ReleasePhase.IDLE:
            self.phase, self.filtered = ReleasePhase.BASELINE, force.copy()
        self.filtered = self.filtered + self.alpha * (force - self.filtered)
        if self.phase is ReleasePhase.BASELINE:
            self._sum, self._count = self._sum + force, self._count + 1
            if self._count >= self.baseline_cycles:
                self.baseline, self.phase = self._sum / self._count, ReleasePhase.ARMED
            return False
        assert self.baseline is not None, "F₀ is set when the phase turns ARMED"
        self.pull = norm(self.filtered - self.baseline)
        if self.pull >= self.config.threshold_n:
            self.phase = ReleasePhase.RELEASED
            return True
        return False

    @property
    def grasped(self) -> bool:
        return self.phase is ReleasePhase.ARMED
