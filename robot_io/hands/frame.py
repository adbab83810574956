"""Tracker frame → robot base frame: a rigid transform, and its calibration from point pairs (Kabsch).

Calibration (``docs/hardware.md``): put a tracked marker at the TCP (or a known offset from it), move
the arm to N ≥ 3 poses that are not on one line (better: 6–10 spread over the workspace), and at each
record the marker in tracker coordinates and the TCP position read from the arm. :func:`fit_kabsch`
returns the rotation R and translation t minimising Σ‖R pᵢ + t − qᵢ‖² and the RMS residual, which
says how well the calibration holds (a few mm with a good mocap system).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from robot_io.errors import ConfigError


class FrameTransform(NamedTuple):
    """x_base = R · (units_to_m · x_tracker) + t."""

    rotation: np.ndarray
    translation: np.ndarray
    units_to_m: float = 1.0

    def apply(self, point: np.ndarray) -> np.ndarray:
        return self.rotation @ (np.asarray(point, dtype=float) * self.units_to_m) + self.translation

    def invert(self, base_point: np.ndarray) -> np.ndarray:
        """Robot base [m] → tracker coordinates (tracker units): the inverse of :meth:`apply`."""
        return self.rotation.T @ (np.asarray(base_point, dtype=float) - self.translation) / self.units_to_m

    @classmethod
    def identity(cls) -> FrameTransform:
        return cls(np.eye(3), np.zeros(3))


def fit_kabsch(tracker: np.ndarray, base: np.ndarray) -> tuple[FrameTransform, float]:
    """Best rigid transform taking ``tracker`` points (N×3, metres) onto ``base`` points (N×3).

    Returns the transform and the RMS residual [m]. Raises ConfigError for fewer than 3 pairs or
    points on (nearly) one line, for which the rotation is not determined.
    """
    p, q = np.asarray(tracker, dtype=float), np.asarray(base, dtype=float)
    if p.shape != q.shape or p.ndim != 2 or p.shape[1] != 3 or len(p) < 3:
        raise ConfigError(f"calibration needs N ≥ 3 point pairs of shape N×3, got {p.shape} and {q.shape}")
    p_mean, q_mean = p.mean(axis=0), q.mean(axis=0)
    spread = np.linalg.svd(p - p_mean, compute_uv=False)
    if spread[1] < 1e-3 * max(spread[0], 1e-12):
        raise ConfigError("calibration points lie on one line: the rotation is not determined; "
                          "use poses spread over the workspace")
    u, _, vt = np.linalg.svd((p - p_mean).T @ (q - q_mean))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    translation = q_mean - rotation @ p_mean
    transform = FrameTransform(rotation, translation)
    residual = float(np.sqrt(np.mean(np.sum((p @ rotation.T + translation - q) ** 2, axis=1))))
    return transform, residual
