"""Tests that run a control loop on the wall clock inside the test process run it as a lab does:
under SCHED_FIFO (where the OS allows it), so that the suite's own load cannot make them late; and
tests of a machine that does not allow it run their command under :func:`without_priority`."""

from __future__ import annotations

import contextlib
import os
import sys
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


#: ``python -m app.cli`` as a command that runs under SCHED_FIFO at SUPPORT_PRIORITY once its
#: interpreter has started and imported the CLI (every thread it starts inherits it, as a rig's do).
#: Started from a FIFO thread instead, the interpreter's start-up ran under FIFO too and held the
#: other FIFO threads on its core (robot_io.clock.children_start_on_the_normal_policy).
REALTIME_CLI = [sys.executable, "-c", "import sys, app.cli; from robot_io.clock import SUPPORT_PRIORITY, "
                "raise_priority; raise_priority(SUPPORT_PRIORITY); sys.exit(app.cli.main())"]


def without_priority() -> list[str]:
    """A command prefix under which a process may not have SCHED_FIFO, as on a lab PC where nobody
    granted it: an rtprio limit of 0 (``prlimit``) and, for root, no CAP_SYS_NICE (``setpriv``
    drops it from the bounding set, so the command never gains it)."""
    prefix = ["prlimit", "--rtprio=0"]
    if os.geteuid() == 0:
        prefix += ["setpriv", "--bounding-set", "-sys_nice", "--"]
    return prefix
