"""``serve`` closed while pages of the tablet and the dashboard open and leave and views are
published (docs/architecture.md, "Shared objects and their lifetimes": viser's client handles, the
live view's ticker, the servers), in a child process (support.lifetimes) so that a crash fails the
test with its signal; ``make soak`` runs 500 cycles beside a CPU hog."""

from __future__ import annotations

from support.lifetimes import stress_marks, survive

pytestmark = stress_marks()


def test_serve_closed_while_pages_come_and_go():
    survive("serve", 2)
