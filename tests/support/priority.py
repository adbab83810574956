"""Tests that run a control loop on the wall clock inside the test process run it as a lab does:
under SCHED_FIFO (where the OS allows it), so that the suite's own load cannot make them late."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

from robot_io.clock import SUPPORT_PRIORITY, raise_priority


@contextlib.contextmanager
def realtime_threads(priority: int = SUPPORT_PRIORITY) -> Iterator[None]:
    """The calling thread, and every thread it starts meanwhile (a tracker's replay, a hand
    source's receiver), under SCHED_FIFO at ``priority``, as in a rig process run with
    ``[loop] realtime_priority``; the thread's own policy again on the way out."""
    before = raise_priority(priority)
    try:
        yield
    finally:
        if before is not None:
            policy, level = before
            os.sched_setscheduler(0, policy, os.sched_param(level))
