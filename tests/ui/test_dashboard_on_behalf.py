"""The dashboard's "Enter for the participant", in headless Chromium against `handover serve`: the
experimenter enters a placement at a scale position and one "the same as" an earlier handover; the
tablet moves on as if the participant had confirmed; the third is placed on the tablet by touch. The
store and its export tell the experimenter's entries from the participant's own. The tablet's
deliberate-answer rule holds for the experimenter too: nothing is stored from an untouched slider
(issue 45, item 15), and a session without coactive hints shows no hint buttons."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from support.browser import (
    button,
    chromium,
    click,
    confirm_placement,
    open_folder,
    open_participant,
    open_screens,
    run_trial,
    serve,
    shot,
    tablet_screen,
    touch_drag_to,
    wait_enabled,
    wait_text,
)

from session_store.export import export_study, read_table

pytestmark = [pytest.mark.browser, pytest.mark.slow]

STORE = "Store the placement for the participant"
SHOTS = Path("/tmp/dashboard-shots")


def test_the_experimenter_enters_placements_for_the_participant(tmp_path: Path) -> None:
    """Slow: each placement entered on the dashboard follows a handover run on the wall clock, through
    `handover serve` and both screens in Chromium."""
    with serve(tmp_path) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        open_participant(dashboard, "P01")
        open_folder(dashboard, "Enter for the participant")
        wait_text(dashboard, "Nothing to enter now.")
        assert button(dashboard, STORE).is_disabled()  # nothing waits for a placement yet

        assert dashboard.get_by_role("button", name=re.compile("^They said")).count() == 0

        assert run_trial(dashboard, tablet) == "place"
        wait_text(dashboard, "The participant places handover 1")
        assert button(dashboard, STORE).is_disabled()  # the slider untouched: nothing to store
        button(dashboard, STORE).scroll_into_view_if_needed()
        shot(dashboard, SHOTS, "dashboard-on-behalf-untouched")
        slider = dashboard.get_by_role("slider")
        slider.focus()
        for _ in range(20):  # the experimenter moves it: 0.5 → 0.3 in steps of 0.01
            slider.press("ArrowLeft")
        wait_enabled(dashboard, STORE)
        click(dashboard, STORE)
        assert tablet_screen(tablet, not_="place") == "wait"  # the tablet moves on

        assert run_trial(dashboard, tablet) == "place"
        wait_text(dashboard, "The participant places handover 2")
        assert slider.get_attribute("aria-valuenow") == "0.5"  # where the tablet's handle starts
        assert button(dashboard, STORE).is_disabled()
        dashboard.locator("xpath=//*[normalize-space(text())='Or the same as']"
                          "/following::input[1]").click()
        dashboard.get_by_role("option", name="handover 1").click()
        button(dashboard, STORE).scroll_into_view_if_needed()
        shot(dashboard, SHOTS, "dashboard-on-behalf")
        wait_enabled(dashboard, STORE)  # an earlier handover chosen: a deliberate entry
        click(dashboard, STORE)
        assert tablet_screen(tablet, not_="place") == "wait"

        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.8)
        confirm_placement(tablet)  # the participant's own, on the tablet
        wait_text(dashboard, "3 of 9 handovers completed")
        served.shutdown()
    export_study(served.study, tmp_path / "export")
    placements = read_table(tmp_path / "export", "placements").set_index("interaction")
    assert placements["actor"].to_dict() == {1: "experimenter", 2: "experimenter",
                                             3: "participant"}
    assert placements.loc[1, "position"] == pytest.approx(0.3)
    assert placements.loc[2, "equal_to"] == 1
    assert placements.loc[3, "position"] == pytest.approx(0.8, abs=0.01)
    events = read_table(tmp_path / "export", "events")
    placed = events[events["kind"] == "placement_made"]["actor"].tolist()
    assert placed == ["experimenter", "experimenter", "participant"]
