"""Two dashboard windows on one session (issue 37, item 13).

Each window is told that the other is open (how many, from where); the first controls, the second is
view-only (Start locked, saying why) until the experimenter takes control on it, which makes the
first view-only. STOP ARM works from the view-only window.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import (
    READY_TO_START,
    button,
    chromium,
    click,
    open_page,
    open_participant,
    serve,
    shot,
    tick,
    unlock_dashboard,
    wait_enabled,
    wait_gone,
    wait_text,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

VIEW_ONLY = "This window is view-only"
CONTROLS = "This window controls the session"


def test_a_second_window_is_told_of_the_first_and_takes_control_only_when_asked(
        tmp_path: Path) -> None:
    """Slow: `handover serve` and two dashboard windows in Chromium, each connecting and drawing,
    control handed over and back, a stop and a re-arm; no trial runs."""
    screens = tmp_path / "screens"
    with serve(tmp_path) as served, chromium() as browser:
        first = open_page(browser, served.dashboard_url, size=(1280, 720))
        open_participant(first, "P01")
        # no tablet needed: the simulated participant rates on the mock arm
        tick(first, "Simulated participant rates", "simulated participant on")
        wait_text(first, READY_TO_START)
        second = open_page(browser, served.dashboard_url, size=(1440, 900))
        unlock_dashboard(second)
        for page in (first, second):
            wait_text(page, "2 dashboard windows are open (127.0.0.1, 127.0.0.1)")
        wait_text(first, CONTROLS)
        wait_text(second, VIEW_ONLY)
        wait_text(second, "View-only window · Ready — press Start trial")  # the status line
        wait_text(second, "Start is locked: this window is view-only")
        assert button(second, "Start trial").is_disabled()
        assert button(first, "Start trial").is_enabled()
        shot(second, screens, "second-window-view-only")

        click(second, "STOP ARM")  # STOP works from a view-only window
        for page in (first, second):
            wait_text(page, "Arm stopped — make sure the scene is safe")
        assert button(second, "Re-arm (scene is safe)").is_disabled()
        click(first, "Re-arm (scene is safe)")
        wait_text(second, READY_TO_START)

        click(second, "Take control")
        wait_text(second, CONTROLS)
        wait_text(first, VIEW_ONLY)
        wait_enabled(second, "Start trial")
        wait_text(first, "Start is locked: this window is view-only")
        assert button(first, "Start trial").is_disabled()
        shot(first, screens, "first-window-view-only")

        second.close()  # the controlling window closes: the one left controls
        wait_gone(first, "dashboard windows are open")
        wait_enabled(first, "Start trial")
        served.shutdown()
