"""Norms and checks of the control loop's 3-vectors, the same results as NumPy's general functions
without their dispatch: at three elements ``np.linalg.norm`` costs ~3 µs where the arithmetic takes
nanoseconds, and a 500 Hz cycle takes several (``benchmarks/control_loop.py``)."""

from __future__ import annotations

import math

import numpy as np


def norm(vector: np.ndarray) -> float:
    """‖v‖₂ of a 1-D float array: √(v·v), the very float ``np.linalg.norm`` computes for it."""
    return math.sqrt(vector.dot(vector))


def all_finite(vector: np.ndarray) -> bool:
    """No NaN and no ±inf in ``vector``: ``np.all(np.isfinite(vector))``."""
    return bool(np.isfinite(vector).all())


def written(vector: np.ndarray | tuple[float, ...]) -> str:
    """A vector as a person writes it in a message, ``(0.35, -0.35, 0.35)``, never
    ``(np.float64(0.35), …)``."""
    return "(" + ", ".join(f"{float(v):g}" for v in vector) + ")"
