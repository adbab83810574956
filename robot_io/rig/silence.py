"""Silence as a watcher saw it: how long something has given no sign of life, counting only the time
the watcher itself ran.

Both sides of the rig watch the other: the rig's inbox thread the application's heartbeats
(``APP_SILENCE_S``), the application's watchdog thread the rig's sample rows (``HANG_S``). Each looks
every ``period`` seconds. A look that comes back later than asked means the watcher was not run for
the difference: the machine held still (a VM paused by its host, every process frozen together), and
what it watches could not have run either. That time is not counted against the watched side, so a
freeze of everything is not taken for a hang of one; the watcher judges again as soon as it runs,
so the stop it owes comes no later than it could have acted anyway. One object per watcher, owned by
its thread. :func:`waited` is the same rule for a thread that waits for something with a limit (a
Stop's acknowledgement, a thread to end): a machine held still does not use the limit up.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class WatchedSilence:
    """The silence since the last sign of life, less the watcher's own lateness."""

    def __init__(self, period: float, now: float) -> None:
        #: how long after it was asked for a look is due [s]
        self.period = period
        #: when the last sign of life came (monotonic clock) [s]
        self.heard_at = now
        #: of the silence since ``heard_at``, how long the watcher itself was not run [s]
        self.unwatched = 0.0

    def heard(self, now: float) -> None:
        """A sign of life at ``now``: the silence starts again."""
        self.heard_at, self.unwatched = now, 0.0

    def looked(self, asked: float, now: float) -> None:
        """A look asked for at ``asked`` (due ``period`` later) came at ``now``."""
        self.unwatched += max(0.0, now - asked - self.period)

    def silent(self, now: float) -> float:
        """The whole silence, as the clock measures it [s]."""
        return now - self.heard_at

    def watched(self, now: float) -> float:
        """The silence the watcher was run for: what it may judge [s]."""
        return self.silent(now) - self.unwatched


def waited(done: Callable[[float], bool], limit: float, look: float) -> bool:
    """Whether ``done(look)`` — a wait of its own of at most ``look`` seconds, True once what it
    waits for has come — says True within ``limit`` seconds of the calling thread's own running
    (:class:`WatchedSilence`: a look that comes back late does not count its lateness)."""
    silence = WatchedSilence(look, time.monotonic())
    while True:
        asked = time.monotonic()
        if done(look):
            return True
        now = time.monotonic()
        silence.looked(asked, now)
        if silence.watched(now) >= limit:
            return False
