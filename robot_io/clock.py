"""The control loop's two clocks: one code path, either real time or simulated time.

``wait_next_cycle`` blocks until the next cycle's start and says how late it is and whether the
previous cycle missed its deadline. The real
clock keeps a fixed grid (deadline n·period) and catches up after a late cycle instead of drifting.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Annotated, Literal, NamedTuple, Protocol

from pydantic import BeforeValidator

from robot_io.errors import ConfigError

log = logging.getLogger(__name__)


#: How many (monotonic, UTC, monotonic) readings :func:`utc_minus_monotonic` takes at most, and the
#: bracket it accepts at once [s].
OFFSET_READINGS, TIGHT_BRACKET_S = 8, 20e-6


def utc_minus_monotonic() -> float:
    """UTC (``time.time()``) − ``time.monotonic()`` now [s], from the tightest of up to
    OFFSET_READINGS brackets monotonic → UTC → monotonic (the UTC reading against the brackets'
    midpoint). Two clock readings in a row differ by however long the thread was preempted between
    them, milliseconds on a loaded machine (an LSL marker then sat 8 ms off its stored time); the
    tightest bracket is off by at most half its width, microseconds."""
    width, offset = math.inf, 0.0
    for _ in range(OFFSET_READINGS):
        before = time.monotonic()
        utc = time.time()
        after = time.monotonic()
        if after - before < width:
            width, offset = after - before, utc - (before + after) / 2.0
        if width <= TIGHT_BRACKET_S:
            break
    return offset


def utc_of_monotonic(monotonic: float) -> datetime:
    """The UTC time (stored rows) of a ``time.monotonic()`` reading of this machine (the rig's stage
    times, the LSL clock: ``pylsl.local_clock()`` is CLOCK_MONOTONIC on Linux), through the offset
    between the two clocks now (:func:`utc_minus_monotonic`)."""
    return datetime.fromtimestamp(monotonic + utc_minus_monotonic(), UTC)


def monotonic_of_utc(at: str | datetime) -> float:
    """The ``time.monotonic()`` reading of a stored UTC time (ISO-8601), the inverse of
    :func:`utc_of_monotonic`: exact to the microseconds a stored time keeps, as long as nobody sets
    the wall clock in between."""
    when = datetime.fromisoformat(at) if isinstance(at, str) else at
    return when.timestamp() - utc_minus_monotonic()


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

    def align(self) -> None:
        """Start the cycle grid now: the first cycle begins here, after the set-up that follows
        start() (Go), so that set-up is not counted as the first cycles' lateness."""

    def wait_next_cycle(self) -> CycleStart:
        """Block until the next cycle starts."""

    def stop(self) -> None:
        """The loop has ended: undo whatever start() changed for the calling thread."""


#: SCHED_FIFO priorities where the OS allows it (root or CAP_SYS_NICE). The control loop's thread
#: runs above every other real-time thread: the rig's own (hand receiver, ur_rtde's, the inbox) and a
#: rehearsal's stand-in controller and hand publisher, which stand for hardware with cores of its
#: own. At equal priority, FIFO threads run until they block, so on a 2-core machine three busy ones
#: could hold a woken control thread back for a whole cycle.
CONTROL_PRIORITY = 50
SUPPORT_PRIORITY = 40


def raise_priority(priority: int = CONTROL_PRIORITY) -> tuple[int, int] | None:
    """Run the calling thread under SCHED_FIFO at ``priority`` where permitted, so a browser or the
    learner on the same cores cannot delay it; return the policy and priority it had, or None if it
    keeps the normal policy. Threads it starts afterwards inherit the policy. The loop sleeps
    between cycles and Linux keeps 5 % of each second for other tasks, so this cannot starve the
    machine."""
    try:
        before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, PermissionError, OSError) as exc:
        log.info("control thread keeps the normal scheduling policy (%s)", exc)
        return None
    return before


def priority_setting(value: object) -> object:
    """``[loop] realtime_priority`` as written: true, false or "auto", nothing else (pydantic would
    read "yes", "on", "true" or 1 as true, a lab's guess read as a setting it did not make)."""
    if value is True or value is False or value == "auto":
        return value
    raise ValueError('must be true, false or "auto" (without quotes: true, false; with: "auto")')


#: ``[loop] realtime_priority``: "auto" runs the rig under SCHED_FIFO where the OS permits it and says
#: so where it does not; true refuses to start without it; false never asks for it.
PrioritySetting = Annotated[bool | Literal["auto"], BeforeValidator(priority_setting)]

#: How a lab grants the rig real-time priority, for the messages that say it runs without.
GRANT_PRIORITY = ("grant it with `sudo setcap cap_sys_nice+ep` on the venv's python (the real file, "
                  "`readlink -f .venv/bin/python`), or an rtprio limit for the lab's user in "
                  "/etc/security/limits.conf (`labuser - rtprio 60`, then log in again), or run as "
                  "root; see docs/hardware.md, \"Real-time priority\"")


def priority_refusal() -> str | None:
    """Why this process may not run threads under SCHED_FIFO (the OS's words), or None if it may.
    Asks on a thread of its own, which ends at once, so no thread of the caller changes policy."""
    refusal: list[str | None] = [None]

    def probe() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(CONTROL_PRIORITY))
        except AttributeError:
            refusal[0] = "this OS has no SCHED_FIFO"
        except OSError as exc:
            refusal[0] = f"the OS refused SCHED_FIFO: {exc.strerror or exc}"

    thread = threading.Thread(target=probe, name="priority-probe")
    thread.start()
    thread.join()
    return refusal[0]


def resolve_priority(setting: PrioritySetting) -> tuple[bool, str | None]:
    """Whether the rig asks for SCHED_FIFO under ``setting``, and what to tell the experimenter at
    start (None: nothing). ``True`` where it is refused raises :class:`ConfigError` with the OS's
    reason and how to grant it; ``"auto"`` then runs on the normal policy and says so."""
    if setting is False:
        return False, None
    refusal = priority_refusal()
    if refusal is None:
        return True, None
    if setting is True:
        raise ConfigError(f"[loop] realtime_priority = true (or --realtime-priority), but {refusal}: "
                          f"{GRANT_PRIORITY}; or set realtime_priority = \"auto\" to run without")
    return False, (f"the rig runs without real-time priority ({refusal}): on a busy machine its "
                   f"control loop and tracker can run late and trials abort; {GRANT_PRIORITY}")


@contextlib.contextmanager
def children_start_on_the_normal_policy() -> Iterator[int | None]:
    """Processes the calling thread starts meanwhile begin on the normal policy; yields the SCHED_FIFO
    priority the thread had (None: it had none), for the child to raise itself to once started.

    A child inherits its parent thread's policy, and a Python interpreter starting (under spawn it
    also runs the parent's main module again, then imports what it needs) is a fraction of a second
    to seconds of CPU with nothing to block on: under SCHED_FIFO it held other FIFO threads on its
    core that long, among them the rehearsal's tracker, whose samples then came 0.1 s late."""
    try:
        policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    except (AttributeError, OSError):
        yield None
        return
    if policy != os.SCHED_FIFO:
        yield None
        return
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    try:
        yield param.sched_priority
    finally:
        os.sched_setscheduler(0, policy, param)


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

    def align(self) -> None:
        pass  # set-up takes no simulated time

    def wait_next_cycle(self) -> CycleStart:
        self._cycle += 1
        return CycleStart(0.0, False)

    def stop(self) -> None:
        pass


class RealClock:
    """Wall-clock time from ``time.monotonic``.

    Sleeps until ``spin_s`` before the deadline, then spins: ``time.sleep`` alone overshoots by tens to
    hundreds of µs, a large share of a 2 ms period. Starting it lowers the interpreter's thread switch
    interval so that a busy thread holding the GIL delays a cycle by at most a fraction of a period.
    With ``realtime_priority`` it also runs the calling thread under SCHED_FIFO where the OS allows it
    (root or CAP_SYS_NICE): with a browser and the learner on a 2-core machine this took 500 Hz
    deadline misses from 2.5 % to 0.1–0.3 %. The garbage collector is off between start() and
    stop(): a trial allocates little that is cyclic, while one full collection of a process's heap
    pauses every thread for milliseconds, several cycles. :meth:`stop` undoes all three.
    A cycle more than ``resync_cycles`` late moves the grid instead of catching up in a burst.
    """

    realtime = True

    def __init__(self, rate_hz: float, spin_s: float = 2e-4, resync_cycles: int = 10,
                 realtime_priority: bool = False) -> None:
        self.period = 1.0 / rate_hz
        self.realtime_priority = realtime_priority
        self.spin_s = spin_s
        self.resync_cycles = resync_cycles
        self._origin = time.monotonic()
        self._next = 0.0
        self._switch_interval: float | None = None
        self._policy_before: tuple[int, int] | None = None
        self._collector_was_enabled = False

    @property
    def priority_raised(self) -> bool:
        """The control thread runs under SCHED_FIFO (between start() and stop())."""
        return self._policy_before is not None

    def stop(self) -> None:
        """Give the thread back its scheduling policy and the interpreter its switch interval."""
        if self._policy_before is not None:
            policy, priority = self._policy_before
            os.sched_setscheduler(0, policy, os.sched_param(priority))
            self._policy_before = None
        if self._switch_interval is not None:
            sys.setswitchinterval(self._switch_interval)
            self._switch_interval = None
        if self._collector_was_enabled:
            gc.enable()
            self._collector_was_enabled = False

    def start(self) -> None:
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_interval, self.period / 10.0))
        self._policy_before = raise_priority() if self.realtime_priority else None
        self._collector_was_enabled = gc.isenabled()
        gc.disable()
        self._origin = time.monotonic()
        self._next = 0.0

    def now(self) -> float:
        return time.monotonic() - self._origin

    def align(self) -> None:
        self._next = self.now()

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
