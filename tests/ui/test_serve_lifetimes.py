"""``serve`` closed while pages of the tablet and the dashboard open and leave and views are
published (docs/architecture.md, "Shared objects and their lifetimes": viser's client handles, the
live view's ticker, the servers), in a child process (support.lifetimes) so that a crash fails the
test with its signal; ``make soak`` runs 500 cycles beside a CPU hog."""

from __future__ import annotations

from support.lifetimes import stress_marks, survive

pytestmark = stress_marks()


def test_serve_closed_while_pages_come_and_go():
    """Slow (20-30 s in a loaded full run): the scenario runs in a child process that imports the
    application, and its first cycle's close waits for the session's learner warm-up (the
    forkserver's torch import; app/session/engine_side.py, WARM_UP_WAIT_S)."""
    survive("serve", 2)
