"""Minimum-jerk point-to-point motion (Flash & Hogan), the default demonstration and the simulated hand.

x(t) = x0 + (x1 − x0)(10τ³ − 15τ⁴ + 6τ⁵), τ = t/T clipped to [0, 1].
"""

from __future__ import annotations

import numpy as np


def minimum_jerk(
    start: np.ndarray, end: np.ndarray, duration: float, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of a minimum-jerk reach sampled at times ``t``.

    Returns three arrays of shape ``(len(t), dim)``; before 0 the motion rests at ``start``, after
    ``duration`` at ``end``.
    """
    if duration <= 0:
        raise ValueError(f"duration = {duration!r} must be > 0")
    start = np.asarray(start, dtype=float)
    delta = np.asarray(end, dtype=float) - start
    u = np.clip(np.asarray(t, dtype=float) / duration, 0.0, 1.0)[:, None]
    moving = ((t > 0) & (t < duration))[:, None]
    pos = start + delta * (10 * u**3 - 15 * u**4 + 6 * u**5)
    vel = np.where(moving, delta * (30 * u**2 - 60 * u**3 + 30 * u**4) / duration, 0.0)
    acc = np.where(moving, delta * (60 * u - 180 * u**2 + 120 * u**3) / duration**2, 0.0)
    return pos, vel, acc
