"""One tablet per session: a page on the tablet port is offered only the pairing code until the code
is typed; the paired page is the study's tablet; a second page of that device is told it is not in
use and is offered nothing to rate, until the first one closes. And input inside the settle window
after a screen change does not count.

In process: a real :class:`SessionRunner` (real engine, store, rig and learner processes, the
experimenter's confirmations automatic) behind a real viser server, pages in headless Chromium with
touch, so :meth:`Tablet.connected_count` is read directly. The settle windows run on the test's own
clock: a window ends when the test advances the clock, never because the machine was slow.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import (
    button,
    chromium,
    fill,
    open_page,
    tablet_screen,
    tap,
    touch_drag_to,
    wait_enabled,
)
from support.waiting import wait_for

from app.session.config import LabConfig
from app.session.runner import SessionRunner
from app.ui.deliberate import SETTLE_S
from app.ui.guard import open_server
from app.ui.tablet import Tablet
from robot_io.hands.simulated_hand import Scenario

pytestmark = [pytest.mark.browser, pytest.mark.slow]

LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": {
    "initial_trials": 2, "batch_size": 2, "learning_batches": 0, "without_learning": True, "best_trials": 0,
    "validation_batches": 0}})


class Clock:
    """The settle windows' clock: it moves only when the test says time has passed."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now += seconds


def pages_open(tablet: Tablet, count: int) -> None:
    wait_for(lambda: tablet.connected_count() == count, f"{count} page(s) open on the tablet port",
             seen=lambda: f"{tablet.connected_count()} open")


def test_a_second_page_is_not_offered_the_scale(tmp_path: Path) -> None:
    """Slow: a session's first handover on the wall clock (rig under SCHED_FIFO, the learner's
    imports) up to its placement, with two tablet pages open in Chromium."""
    # the rig under SCHED_FIFO, as the served tests run it: at normal priority a full run starved
    # it for 0.5 s mid-reach, the backstop killed it as designed, and the trial was never placed
    runner = SessionRunner(tmp_path / "study", LAB, auto_experimenter=True, realtime_priority=True)
    clock = Clock()
    server, guard = open_server("127.0.0.1", 0, "tablet")  # any free port: the one bound is used
    tablet = Tablet(server, runner, guard.source_of, clock=clock)
    url = f"http://127.0.0.1:{server.get_port()}"
    try:
        with chromium() as browser:
            assert tablet.connected_count() == 0
            first = open_page(browser, url, touch=True, size=(1180, 820))
            pages_open(tablet, 1)
            assert tablet_screen(first, unused_ok=True) == "pair"
            assert runner.view.tablet.blocker().startswith("the tablet is not paired")
            # The window started before the screen reached the page (app/ui/tablet.py _draw).
            clock.advance(SETTLE_S)  # the participant has read the pairing screen
            fill(first, "Code", "0000" if tablet.pairing.code != "0000" else "1111")
            tap(first, "Connect")
            first.get_by_text("Wrong code").wait_for()
            fill(first, "Code", tablet.pairing.code)
            tap(first, "Connect")
            assert tablet_screen(first) == "wait"
            assert runner.view.tablet.ready
            runner.open("P01", Scenario.STRAIGHTFORWARD)  # the first trial starts by itself
            assert tablet_screen(first, not_="wait") == "go"
            second = open_page(browser, url, touch=True, size=(820, 1180))
            pages_open(tablet, 2)
            assert tablet_screen(second, unused_ok=True) == "unused"  # not even "Go!"
            assert runner.view.tablet.blocker().startswith("2 pages are open")
            assert tablet_screen(first, not_=("go", "back")) == "place"
            assert tablet_screen(second, unused_ok=True) == "unused"
            assert second.locator(".mantine-Slider-root, .hl-scale").count() == 0
            assert second.get_by_role("button").count() == 0  # nothing to tap at all

            first.close()  # the study's tablet closes: the other page takes over
            pages_open(tablet, 1)
            assert tablet_screen(second) == "place"
            assert second.locator(".hl-scale").count() == 1
            # A drag inside the settle window (the clock has not moved since the scale was drawn,
            # however long the drag took): the server redraws the handle but does not count it.
            touch_drag_to(second, 0.8, settled=False)
            # A watch for something that must not happen (Confirm enabled by that drag; viser runs
            # the slider's callback in a thread, so its last message may trail the marker's): load
            # can only make the watch shorter in effect, never fail a Confirm that stays disabled.
            second.wait_for_timeout(500)
            assert button(second, "Confirm").is_disabled()
            clock.advance(SETTLE_S)  # the screen has now been shown for the whole window
            touch_drag_to(second, 0.3, settled=False)  # counted: the handle moved, Confirm enabled
            wait_enabled(second, "Confirm")
    finally:
        runner.close()
        server.stop()
