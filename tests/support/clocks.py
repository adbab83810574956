"""Clock offsets measured by the tests themselves, independently of the product's mapping."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

#: How often a :class:`ClockWatch` measures the offset [s].
WATCH_S = 0.01


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


class ClockWatch:
    """UTC − ``time.monotonic()`` measured every :data:`WATCH_S` from a thread of its own (which
    owns the readings until :meth:`stop`) while something runs on the wall clock: a machine's wall
    clock can be stepped (a virtual machine's after it was held still; CI saw an LSL marker 78 ms
    off its stored time through a single offset read after the session, while the markers agreed
    with the robot samples to 10 µs), and a stored UTC time maps onto the monotonic clock through
    the offset in effect when it was mapped."""

    def __init__(self, readings: int = 20) -> None:
        self._readings = readings
        self._seen: list[tuple[float, float]] = []  # (monotonic, offset)
        self._stopping = threading.Event()
        self._take()
        self._thread = threading.Thread(target=self._run, name="clock-watch", daemon=True)
        self._thread.start()

    def _take(self) -> None:
        self._seen.append((time.monotonic(), utc_minus(time.monotonic, self._readings)))

    def _run(self) -> None:
        while not self._stopping.wait(WATCH_S):
            self._take()

    def stop(self) -> np.ndarray:
        """The readings, (monotonic, UTC − monotonic) per row, the last one taken now."""
        self._stopping.set()
        self._thread.join()
        self._take()
        return np.array(self._seen)


def offsets_around(seen: np.ndarray, monotonic: float, after_s: float) -> np.ndarray:
    """The offsets a :class:`ClockWatch` saw that can have been in effect from ``monotonic`` to
    ``after_s`` later: the last reading before it and every reading until then (one value unless
    the wall clock was stepped then)."""
    first = max(int(np.searchsorted(seen[:, 0], monotonic)) - 1, 0)
    last = int(np.searchsorted(seen[:, 0], monotonic + after_s)) + 1
    return seen[first:last, 1]


def wall_clock_steps(seen: np.ndarray, tolerance_s: float = 1e-3) -> list[tuple[float, float]]:
    """Where the wall clock was stepped against the monotonic clock by more than ``tolerance_s``:
    (monotonic, step [s]) of each."""
    jumps = np.diff(seen[:, 1])
    return [(float(seen[i + 1, 0]), float(jumps[i])) for i in np.flatnonzero(np.abs(jumps) > tolerance_s)]
