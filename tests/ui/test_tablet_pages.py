"""One tablet per session: a page on the tablet port is offered only the pairing code until the code
is typed; the paired page is the study's tablet; a second page of that device is told it is not in
use and is offered nothing to rate, until the first one closes. And input inside the settle window
after a screen change does not count.

In process: a real :class:`SessionRunner` (real engine, store, rig and learner processes, the
experimenter's confirmations automatic) behind a real viser server, pages in headless Chromium with
touch, so :meth:`Tablet.connected_count` is read directly.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import pytest
from support.browser import (
    button,
    chromium,
    fill,
    free_port,
    open_page,
    tablet_screen,
    tap,
    touch_drag_to,
)

from app.session.config import LabConfig
from app.session.runner import SessionRunner
from app.ui.guard import open_server
from app.ui.tablet import Tablet
from robot_io.simulated_hand import Scenario

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: A settle window long enough that a drag right after a screen appears falls inside it even on a
#: loaded machine (the study's is 0.4 s).
SETTLE_S = 3.0

LAB = LabConfig.model_validate({"loop": {"rate_hz": 125}, "protocol": {
    "initial_trials": 2, "batch_size": 2, "learning_batches": 0, "best_trials": 0,
    "validation_batches": 0}})


def until(condition: Callable[[], bool], timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not reached"
        time.sleep(0.05)


def test_a_second_page_is_not_offered_the_scale(tmp_path: Path) -> None:
    runner = SessionRunner(tmp_path / "study", LAB, auto_experimenter=True)
    server, guard = open_server("127.0.0.1", free_port(), "tablet")
    tablet = Tablet(server, runner, guard.source_of, settle_s=SETTLE_S)
    url = f"http://127.0.0.1:{server.get_port()}"
    try:
        with chromium() as browser:
            assert tablet.connected_count() == 0
            first = open_page(browser, url, touch=True, size=(1180, 820))
            until(lambda: tablet.connected_count() == 1)
            assert tablet_screen(first, unused_ok=True) == "pair"
            assert runner.view.tablet.blocker().startswith("the tablet is not paired")
            time.sleep(SETTLE_S)
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
            until(lambda: tablet.connected_count() == 2)
            assert tablet_screen(second, unused_ok=True) == "unused"  # not even "Go!"
            assert runner.view.tablet.blocker().startswith("2 pages are open")
            assert tablet_screen(first, not_=("go", "back")) == "place"
            assert tablet_screen(second, unused_ok=True) == "unused"
            assert second.locator(".mantine-Slider-root, .hl-scale").count() == 0
            assert second.get_by_role("button").count() == 0  # nothing to tap at all

            first.close()  # the study's tablet closes: the other page takes over
            until(lambda: tablet.connected_count() == 1)
            assert tablet_screen(second) == "place"
            assert second.locator(".hl-scale").count() == 1
            shown = time.monotonic()
            touch_drag_to(second, 0.8)  # a drag right after the screen appeared: not counted
            assert time.monotonic() - shown < SETTLE_S
            time.sleep(0.5)
            assert button(second, "Confirm").is_disabled()
            time.sleep(SETTLE_S)
            touch_drag_to(second, 0.3)  # once settled: the handle has moved, Confirm is enabled
            second.wait_for_function("() => [...document.querySelectorAll('button')].some("
                                     "b => !b.disabled && b.innerText.trim() === 'Confirm')")
    finally:
        runner.close()
        server.stop()
