"""Clock offsets measured by the tests themselves, independently of the product's mapping."""

from __future__ import annotations

import time
from collections.abc import Callable


def utc_minus(reference: Callable[[], float], readings: int = 200) -> float:
    """UTC (``time.time()``) − ``reference()`` now [s], from the tightest of ``readings`` brackets
    reference → UTC → reference: a single reading of each clock is off by however long the thread
    was preempted between them (milliseconds on a loaded machine), the tightest bracket by half
    its width."""
    brackets = []
    for _ in range(readings):
        before, utc, after = reference(), time.time(), reference()
        brackets.append((after - before, utc - (before + after) / 2.0))
    return min(brackets)[1]
