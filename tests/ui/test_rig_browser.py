"""`handover serve --rehearse` in headless Chromium: the initial batch driven from the dashboard (Start
trial, Object loaded, Go) and placed on the tablet with touch, through the stand-in UR controller and
the simulated hand on LSL; the dashboard shows each trial's stage of the handover cycle. Then a fault
staged from the dashboard's "Rehearse a fault" panel: a participant who does not take the object."""

from __future__ import annotations

from itertools import count
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    READY_TO_START,
    chromium,
    click,
    confirm_placement,
    open_folder,
    open_participant,
    open_screens,
    publish,
    serve,
    shot,
    shown_screen,
    tablet_screen,
    tick,
    touch_drag_to,
    trial_ended,
    wait_text,
    what_it_showed,
)
from support.repeats import starved, unless_starved
from support.waiting import wait_for

from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.standin]

#: The cycle's stages as the dashboard shows the current one: "[stage]" in bold. Only stages that
#: wait for someone are watched for on the page: prepare and ready wait for the experimenter, and
#: the hold of a participant who does not take the object lasts [release] timeout_s (10 s, the
#: default; the page shows a stage within a second even on a loaded machine). A completing trial's
#: reach and hold last ~1 s and could be over before a loaded browser drew them: the store's stage
#: events prove the rig went through them.
SEEN_STAGES = ("[prepare]", "[ready]", "[hold]")


#: What the dashboard says once a starved trial has ended: ready for the repeat, or the arm's fault
#: to recover from first (app/ui/status_text.py).
AFTER_STARVED = {"ready": READY_TO_START, "fault": "the arm has a fault"}


def watch_stages(dashboard: Page, until: str, seen: set[str]) -> None:
    """Read the dashboard until ``until`` shows, noting every stage it showed on the way; if it
    never does, say what the dashboard showed and what serve logged (at INFO: every message the
    dashboard was sent), to tell a re-locked or stale page from a silent server."""
    def shows() -> bool:
        text = dashboard.inner_text("body")
        seen.update(stage for stage in SEEN_STAGES if stage in text)
        return until in text

    wait_for(shows, f"the dashboard to show {until!r}", seen=lambda: what_it_showed(dashboard))


def start(dashboard: Page, tablet: Page, seen: set[str]) -> None:
    """The experimenter's part of a trial: Start trial, Object loaded, Go, each once the dashboard
    asks for it; the tablet gives no cue before Go."""
    click(dashboard, "Start trial")
    watch_stages(dashboard, "into the gripper, then press", seen)
    assert tablet_screen(tablet) == "wait"  # no cue before Go
    click(dashboard, "Object loaded")
    watch_stages(dashboard, "hand is at the start — press Go", seen)
    click(dashboard, "Go")


def starved_end(dashboard: Page, tablet: Page, index: int, before: str) -> str:
    """Trial ``index`` ended before its subject (``before``: what the test saw of it): it must have
    been the starved machine (support.repeats). Once the dashboard is ready to repeat it (after
    Recover arm when the stand-in controller went silent) and the tablet says "Please wait", the
    reason to start it again."""
    end = wait_for(lambda: trial_ended(dashboard, index), f"the dashboard to say trial {index} ended",
                   seen=lambda: what_it_showed(dashboard))
    assert end[0] == "aborted" and starved(end[1]), f"trial {index} ended {end}; {before}"
    def ready_or_fault() -> str | None:
        text = dashboard.inner_text("body")
        return next((state for state, words in AFTER_STARVED.items() if words in text), None)

    after = wait_for(ready_or_fault, f"the dashboard ready again after trial {index}",
                     seen=lambda: what_it_showed(dashboard))
    if after == "fault":  # the stand-in controller went silent: the arm stopped, as it must
        click(dashboard, "Recover arm (cause inspected)")
        wait_text(dashboard, READY_TO_START)
    assert tablet_screen(tablet, not_=("go", "back")) == "wait"  # an aborted trial is not rated
    return f"trial {index} aborted: {end[1]}"


def handover_to_place(dashboard: Page, tablet: Page, index: int, seen: set[str]) -> str | None:
    """Trial ``index`` up to the tablet's "Place this handover" (None), the tablet showing "Go!"
    from Go until the robot moves back; or the reason to start it again (:func:`starved_end`)."""
    start(dashboard, tablet, seen)
    cue = wait_for(lambda: shown_screen(tablet, not_="wait") or trial_ended(dashboard, index),
                   f"the tablet to show the cue or the dashboard trial {index}'s end",
                   seen=lambda: what_it_showed(tablet))
    if cue == "go" and tablet_screen(tablet, not_=("go", "back")) == "place":
        return None
    return starved_end(dashboard, tablet, index, f"after Go the tablet showed {cue!r}, then "
                                         f"{shown_screen(tablet)!r}")


def held_not_taken(dashboard: Page, tablet: Page, index: int, seen: set[str], screens: Path
                   ) -> tuple[Path | None, str | None]:
    """Trial ``index`` of a participant who does not take the object: held out until the release
    times out (the dashboard's screenshot of its hold), then ``not_taken``; or the reason to start
    it again (:func:`starved_end`)."""
    start(dashboard, tablet, seen)
    held = wait_for(lambda: "[hold]" in dashboard.inner_text("body") or trial_ended(dashboard, index),
                    f"the dashboard to show the hold of trial {index} or its end",
                    seen=lambda: what_it_showed(dashboard))
    if held is not True:
        return None, starved_end(dashboard, tablet, index, "it ended before its hold")
    seen.add("[hold]")
    hold = shot(dashboard, screens, "dashboard-rehearsal-hold")
    end = wait_for(lambda: trial_ended(dashboard, index), f"the dashboard to say trial {index} ended",
                   seen=lambda: what_it_showed(dashboard))
    if end[0] == "not_taken":
        return hold, None
    return None, starved_end(dashboard, tablet, index, "it ended during its hold")


def test_a_rehearsed_batch_driven_from_the_dashboard_and_placed_by_touch(tmp_path: Path) -> None:
    """Slow (about a minute alone, two at a load of 20): three whole handovers on the wall clock
    through the stand-in UR and the LSL hand, each driven by clicks and placed by touch in Chromium,
    then the staged no-pull trial, which waits out the release timeout (10 s)."""
    screens = tmp_path / "screens"
    seen: set[str] = set()
    with serve(tmp_path, "--rehearse") as served, \
            chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        open_participant(dashboard, "P01")
        wait_text(dashboard, "PolyScope 3.15")  # the stand-in's controller, through ur_rtde
        wait_text(dashboard, "LSL stream")
        indices = count(1)  # trial_index: the dashboard counts every trial started
        for position in (0.3, 0.8, 0.55):
            unless_starved("a handover of the batch",
                           lambda: (None, handover_to_place(dashboard, tablet, next(indices), seen)))
            touch_drag_to(tablet, position)
            confirm_placement(tablet)
            assert tablet_screen(tablet, not_="place") == "wait"
        wait_text(dashboard, "3 of 9 handovers completed")
        open_folder(dashboard, "Rehearse a fault")
        tick(dashboard, "The participant does not take the object",
             "the simulated participant will not take the object")
        faults = shot(dashboard, screens, "dashboard-rehearse-a-fault")
        hold = unless_starved("the staged no-pull trial", lambda: held_not_taken(
            dashboard, tablet, next(indices), seen, screens))
        # a handover not taken is never rated: once the page has left the trial's screens (it
        # can draw the robot's way back after the dashboard said the trial ended), "Please wait"
        assert tablet_screen(tablet, not_=("go", "back")) == "wait"
        served.shutdown()
    publish([hold, faults])
    assert seen == set(SEEN_STAGES)
    store = ParticipantStore.open(served.study, "P01")
    try:
        trials = store.rows("trials")
        staged = [(e.payload["trial_index"], e.payload["stage"]) for e in store.events()
                  if e.kind == "trial_stage"]
        devices = [e.payload["devices"] for e in store.events() if e.kind == "devices_recorded"]
        placements = [p.position for p in store.rows("placements")]
    finally:
        store.close()
    repeated = [t for t in trials if starved(t.reason)]  # each a MachineEndedTrial warning
    trials = [t for t in trials if t not in repeated]
    assert [t.outcome.value for t in trials] == ["completed"] * 3 + ["not_taken"]
    assert all(t.release_s > t.hold_s and t.peak_pull_n >= 10.0 for t in trials[:3])
    assert trials[3].release_s is None and trials[3].interaction == 4  # repeated, not rated
    kept = {t.trial_index for t in trials}
    stages = [stage for index, stage in staged if index in kept]
    assert stages[:27] == ["prepare", "loaded", "ready", "go", "reach", "hold", "release",
                           "retract", "done"] * 3, \
        f"stages {stages}; trials {[(t.outcome.value, t.reason, t.retract_fault) for t in trials]}"
    assert "hold" in stages[27:] and "release" not in stages[27:] and stages[-1] == "done"
    assert devices[0]["arm"] == "ur" and devices[0]["hand_source"] == "lsl"
    assert placements == pytest.approx([0.3, 0.8, 0.55], abs=0.01)
