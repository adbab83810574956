"""End-to-end: `handover serve` in a subprocess, the dashboard and the tablet in headless Chromium.

The dashboard's Abort, Stop and reloads (the participant's own tablet tests are in tests/ui/). Abort
and Stop each land in a stage the trial keeps until the experimenter acts (waiting for Object
loaded, waiting for Go), never in one that ends by itself: a stop while the arm holds the object
out is in test_dashboard_safety.py, a stop while it moves in tests/robot_io/control/test_loop.py and
tests/session/test_rehearsal.py.
Screenshots go to the test's tmp folder (and, with HANDOVER_DOC_FIGURES=1, to docs/figures/ for
docs/running-a-study.md).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import (
    chromium,
    click,
    open_folder,
    open_participant,
    open_screens,
    publish,
    reload,
    run_trial,
    serve,
    shot,
    tablet_screen,
    tap,
    touch_drag_to,
    wait_enabled,
    wait_text,
    wait_unlocked,
)

from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_dashboard_abort_stop_and_reload(tmp_path: Path) -> None:
    """Slow: four trials through `handover serve` (one aborted, one stopped while it waits for Go,
    two run on the wall clock and placed), a reload of both pages, and the learner's first model."""
    screens = tmp_path / "screens"
    with serve(tmp_path) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        open_participant(dashboard, "P02")
        # Abort while the trial waits for Object loaded: recorded as aborted, never rated (the
        # tablet goes back to "Please wait").
        click(dashboard, "Start trial")
        click(dashboard, "Abort trial")
        wait_text(dashboard, "aborted by the experimenter")
        assert tablet_screen(tablet, not_="go") == "wait"
        # Stop while the trial waits for Go (the hand rests at A; the trial stays there until Go):
        # the arm stops, the trial is aborted too.
        click(dashboard, "Start trial")
        click(dashboard, "Object loaded")
        wait_enabled(dashboard, "Go")
        wait_text(dashboard, "[ready]")
        click(dashboard, "STOP ARM")
        wait_text(dashboard, "Arm: STOPPED")
        wait_text(dashboard, "stopped by the experimenter (Stop)")
        shot(dashboard, screens, "dashboard-stopped")
        assert tablet_screen(tablet, not_="go") == "wait"
        click(dashboard, "Re-arm (scene is safe)")  # the scene is safe: trials may start again
        # The repeated trial completes and is placed.
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.3)
        tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="place") == "wait"
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.9)  # dragged, not confirmed: then both pages reload
        reload(tablet)
        reload(dashboard)
        assert tablet_screen(tablet) == "place"
        assert "Handover 2" in tablet.inner_text("body")
        assert tablet.locator(".hl-marker").count() == 2  # marker 1 where it was, and the newest
        wait_unlocked(dashboard)  # the browser was unlocked before: no token again
        wait_text(dashboard, "2 of 9 handovers completed")
        shot(tablet, screens, "tablet-after-reload")
        touch_drag_to(tablet, 0.9)
        tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="place") == "wait"
        reload(tablet)
        assert tablet_screen(tablet) == "wait"
        # 2 ≻ 1 gives the learner its first model: θ* and the posterior slices reach the dashboard
        open_folder(dashboard, "Learner")
        wait_text(dashboard, "θ* (best so far)")
        wait_text(dashboard, "u along k")
        shot(dashboard, screens, "dashboard-learner")
        served.shutdown()
    publish([screens / "dashboard-stopped.png", screens / "dashboard-learner.png"])
    store = ParticipantStore.open(served.study, "P02")
    try:
        trials = store.rows("trials", order_by="trial_index")
        stages = [(e.payload["trial_index"], e.payload["stage"]) for e in store.events()
                  if e.kind == "trial_stage"]
        assert [(t.interaction, t.attempt, t.outcome.value) for t in trials] == [
            (1, 1, "aborted"), (1, 2, "aborted"), (1, 3, "completed"), (2, 1, "completed")]
        assert trials[0].reason == "aborted by the experimenter"
        assert trials[1].reason == "stopped by the experimenter (Stop)"
        # each landed where the test acted: the abort before Object loaded, the stop before Go
        assert "loaded" not in [s for i, s in stages if i == 1]
        assert [s for i, s in stages if i == 2] == ["prepare", "loaded", "ready"]
        placements = store.rows("placements")
        assert [(p.interaction, p.trial_index) for p in placements] == [(1, 3), (2, 4)]
        assert placements[0].position == pytest.approx(0.3, abs=0.01)
        assert placements[1].position == pytest.approx(0.9, abs=0.01)
        assert {(c.winner, c.loser) for c in store.rows("comparisons")} == {(2, 1)}
    finally:
        store.close()
