"""After an arm fault and Recover, the dashboard says the session is ready (issue 37, item 12).

The rig process is killed from the rehearsal's fault panel: the arm's fault locks Start, and Recover
arm opens a fresh rig process (moving nothing), after which the status line reads "Ready — press
Start trial" and Start is enabled. (Recover used to be refused with "no rig process is running",
while Start stayed locked by the fault: the status read "Ready, but the arm has a fault" for good.)
A protective stop's recovery: tests/session/test_rehearsal.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import (
    READY_TO_START,
    chromium,
    click,
    open_folder,
    open_page,
    open_participant,
    serve,
    shot,
    tick,
    wait_enabled,
    wait_gone,
    wait_text,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.standin]


def test_recover_after_the_rig_process_died_leaves_the_session_ready(tmp_path: Path) -> None:
    """Slow (about a minute alone): ``serve --rehearse`` starts a stand-in UR, a rig process and the
    learner; the killed rig is replaced by a fresh rig process that connects to the stand-in again,
    all seen through Chromium."""
    screens = tmp_path / "screens"
    with serve(tmp_path, "--rehearse") as served, chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=(1280, 720))
        open_participant(dashboard, "P01")
        # no tablet: the simulated participant rates on the rehearsal rig
        tick(dashboard, "Simulated participant rates", "simulated participant on")
        wait_text(dashboard, READY_TO_START)
        open_folder(dashboard, "Rehearse a fault")
        click(dashboard, "Kill the rig process")
        wait_text(dashboard, "Ready, but the arm has a fault")
        shot(dashboard, screens, "dashboard-rig-killed")
        click(dashboard, "Recover arm (cause inspected)")
        wait_text(dashboard, "a fresh rig process is open")
        wait_text(dashboard, READY_TO_START)
        wait_gone(dashboard, "the arm has a fault")
        wait_enabled(dashboard, "Start trial")
        shot(dashboard, screens, "dashboard-recovered")
        served.shutdown()
