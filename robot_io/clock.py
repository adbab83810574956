"""The control loop's two clocks: one code path, either real time or simulated time.

``wait_next_cycle`` blocks until the next cycle's start and says how late it is and whether the
previous cycle missed its deadline. The real
clock keeps a fixed grid (deadline n·period) and catches up after a late cycle instead of drifting.
"""

from __future__ import annotations

import sys
import time
from typing import NamedTuple, Protocol


class CycleStart(NamedTuple):
    """``lateness``: actual start − scheduled start [s]. ``missed``: the previous cycle's work was
    still running at this cycle's scheduled start (its deadline)."""

    lateness: float
    missed: bool


class Clock(Protocol):
    period: float

    def start(self) -> None:
        """Make now() = 0 (the trial's Go)."""

    def now(self) -> float:
        """Seconds since start()."""

    def wait_next_cycle(self) -> CycleStart:
        """Block until the next cycle starts."""


class SimClock:
    """Simulated time: each cycle advances by exactly one period, as fast as the CPU allows."""

    realtime = False

    def __init__(self, rate_hz: float) -> None:
        self.period = 1.0 / rate_hz
        self._cycle = 0

    def start(self) -> None:
        self._cycle = 0

    def now(self) -> float:
        return self._cycle * self.period

    def wait_next_cycle(self) -> CycleStart:
        self._cycle += 1
        return CycleStart(0.0, False)


class RealClock:
    """Wall-clock time from ``time.monotonic``.

    Sleeps until ``spin_s`` before the deadline, then spins: ``time.sleep`` alone overshoots by tens to
    hundreds of µs, a large share of a 2 ms period. Starting it lowers the interpreter's thread switch
    interval so that a busy thread holding the GIL delays a cycle by at most a fraction of a period.
    A cycle more than ``resync_cycles`` late moves the grid instead of catching up in a burst.
    """

    realtime = True

    def __init__(self, rate_hz: float, spin_s: float = 2e-4, resync_cycles: int = 10) -> None:
        self.period = 1.0 / rate_hz
        self.spin_s = spin_s
        self.resync_cycles = resync_cycles
        self._origin = time.monotonic()
        self._next = 0.0

    def start(self) -> None:
        sys.setswitchinterval(min(sys.getswitchinterval(), self.period / 10.0))
        self._origin = time.monotonic()
        self._next = 0.0

    def now(self) -> float:
        return time.monotonic() - self._origin

    def wait_next_cycle(self) -> CycleStart:
        self._next += self.period
        remaining = self._next - self.now()
        missed = remaining < 0
        if remaining > self.spin_s:
            time.sleep(remaining - self.spin_s)
        while self.now() < self._next:
            pass
        lateness = self.now() - self._next
        if lateness > self.resync_cycles * self.period:
            self._next = self.now()
        return CycleStart(lateness, missed)
