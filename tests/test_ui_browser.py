"""End-to-end: `handover serve` in a subprocess, the tablet and the dashboard in headless Chromium.

The participant's placements are real touch drags; what the store holds afterwards is checked
against what was dragged. Screenshots go to the test's tmp folder (and, with
HANDOVER_DOC_FIGURES=1, to docs/figures/ for docs/running-a-study.md).
"""

from __future__ import annotations

import os
import shutil
import statistics
import time
from pathlib import Path

import pytest
from browser_helpers import (
    Served,
    chromium,
    click,
    confirm_placement,
    open_participant,
    open_screens,
    reload,
    run_trial,
    scale_value,
    serve,
    shot,
    start_trial,
    tablet_screen,
    tap,
    touch_drag_to,
    unlock_dashboard,
    wait_text,
)
from playwright.sync_api import Page

from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

DOC_FIGURES = Path(__file__).parents[1] / "docs" / "figures"
#: Where the participant drags each interaction: a fraction of the scale, or ("equal", label).
DRAGS: dict[int, float | tuple[str, int]] = {1: 0.6, 2: 0.25, 3: 0.8, 4: 0.4, 5: 0.7,
                                             6: ("equal", 1)}
def publish(paths: list[Path]) -> None:
    if os.environ.get("HANDOVER_DOC_FIGURES") == "1":
        DOC_FIGURES.mkdir(exist_ok=True)
        for path in paths:
            shutil.copy(path, DOC_FIGURES / f"ui-{path.name}")


def place_by_touch(tablet: Page, interaction: int, label: int, positions: dict[int, float],
                   batch_labels: dict[int, int]) -> tuple[float | None, int | None]:
    """Drag handover ``interaction`` with one finger as DRAGS says; returns (position, equal_to)."""
    target = DRAGS[interaction]
    if isinstance(target, tuple):
        equal_to = batch_labels[target[1]]
        touch_drag_to(tablet, positions[equal_to])
        wait_text(tablet, f"Same as {target[1]}")
        return None, equal_to
    touch_drag_to(tablet, target)
    assert abs(scale_value(tablet) - target) < 0.01
    return scale_value(tablet), None


def test_participant_session_with_touch(tmp_path: Path) -> None:
    screens = tmp_path / "screens"
    with serve(tmp_path) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        wait_text(tablet, "Please wait")
        shot(tablet, screens, "tablet-wait")
        open_participant(dashboard, "P01")
        dragged: dict[int, tuple[float | None, int | None]] = {}
        positions: dict[int, float] = {}
        batch_labels: dict[int, int] = {}
        latencies: list[float] = []
        interaction, shown = 0, set()
        while True:
            screen = tablet_screen(tablet, not_="go")
            if screen == "wait":
                start_trial(dashboard)
                interaction += 1
                assert tablet_screen(tablet, not_="wait") in ("go", "place", "rate", "Q1")
                if "go" not in shown:
                    assert tablet.locator("audio.hl-cue").count() == 1  # the audible cue
                    tablet.wait_for_function(  # it plays (or has played) without a tap
                        "() => { const a = document.querySelector('audio.hl-cue');"
                        " return a && (!a.paused || a.ended); }", timeout=5000)
                    shot(tablet, screens, "tablet-go")
                    time.sleep(0.4)
                    shot(dashboard, screens, "dashboard-trial")
                    shown.add("go")
                continue
            if screen == "place":
                label = int(tablet.inner_text("body").split("Handover ")[1].split()[0])
                if label == 1:
                    batch_labels.clear()
                batch_labels[label] = interaction
                dragged[interaction] = place_by_touch(tablet, interaction, label, positions,
                                                      batch_labels)
                positions[interaction] = dragged[interaction][0] or positions[
                    dragged[interaction][1]]
                shot(tablet, screens, f"tablet-place-{interaction}")
                latencies.append(confirm_placement(tablet))
            elif screen in ("Q1", "Q2", "Q3"):
                shot(tablet, screens, f"tablet-{screen}")
                tap(tablet, {"Q1": "4", "Q2": "Maybe", "Q3": "5 – Perfectly"}[screen])
                tablet_screen(tablet, not_=screen)
            elif screen == "rate":
                shot(tablet, screens, "tablet-rate")
                tap(tablet, "Better")
                tablet_screen(tablet, not_="rate")
            elif screen == "done":
                shot(tablet, screens, "tablet-done")
                break
        output = served.shutdown()
    assert "stopping the arm" in output and "closed" in output
    publish([screens / f"{n}.png" for n in ("tablet-go", "tablet-place-6", "tablet-Q1",
                                            "tablet-rate", "dashboard-trial")])
    print(f"placement confirmed → next screen: median {statistics.median(latencies) * 1e3:.0f} ms "
          f"over {len(latencies)}")
    check_store(served, dragged)


def check_store(served: Served, dragged: dict[int, tuple[float | None, int | None]]) -> None:
    store = ParticipantStore.open(served.study, "P01")
    try:
        placements = {p.interaction: p for p in store.rows("placements")}
        assert sorted(placements) == sorted(dragged) == [1, 2, 3, 4, 5, 6]
        for interaction, (position, equal_to) in dragged.items():
            stored = placements[interaction]
            assert stored.equal_to == equal_to
            if position is not None:
                assert stored.position == pytest.approx(position, abs=0.002)
        expected = set()
        for batch in ((1, 2, 3), (4, 5, 6)):
            for i, newest in enumerate(batch):
                for earlier in batch[:i]:
                    a, b = placements[newest], placements[earlier]
                    if a.equal_to == earlier or a.position == b.position:
                        continue
                    expected.add((newest, earlier) if a.position > b.position else (earlier, newest))
        stored = {(c.winner, c.loser) for c in store.rows("comparisons")}
        assert stored == expected
        assert (6, 4) not in stored and (4, 6) not in stored  # "equal" makes no comparison
        assert {a.question: a.value for a in store.rows("answers")} == {"Q1": "4", "Q2": "Maybe",
                                                                       "Q3": "5"}
        [rating] = store.rows("validation_ratings")
        assert rating.rating == "better" and rating.interaction == 9
        trials = store.rows("trials")
        assert all(t.outcome.value == "completed" for t in trials) and len(trials) == 9
    finally:
        store.close()


def test_dashboard_abort_stop_and_reload(tmp_path: Path) -> None:
    screens = tmp_path / "screens"
    with serve(tmp_path) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        open_participant(dashboard, "P02")
        # Abort: recorded as aborted, never rated (the tablet goes back to "Please wait").
        click(dashboard, "Start trial")
        click(dashboard, "Abort trial")
        wait_text(dashboard, "aborted by the experimenter")
        assert tablet_screen(tablet, not_="go") == "wait"
        # Stop during the reach: the arm stops, the trial is aborted too.
        start_trial(dashboard)
        wait_text(dashboard, "[reach]")
        click(dashboard, "STOP ARM")
        wait_text(dashboard, "Stop: the arm is stopped")
        wait_text(dashboard, "stopped by the experimenter (Stop)")
        shot(dashboard, screens, "dashboard-stopped")
        assert tablet_screen(tablet, not_="go") == "wait"
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
        unlock_dashboard(dashboard)
        wait_text(dashboard, "2 of 9 handovers completed")
        shot(tablet, screens, "tablet-after-reload")
        touch_drag_to(tablet, 0.9)
        tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="place") == "wait"
        reload(tablet)
        assert tablet_screen(tablet) == "wait"
        # 2 ≻ 1 gives the learner its first model: θ* and the posterior slices reach the dashboard
        dashboard.get_by_text("Learner", exact=True).first.click()
        wait_text(dashboard, "θ* (best so far)")
        wait_text(dashboard, "u along k")
        shot(dashboard, screens, "dashboard-learner")
        served.shutdown()
    publish([screens / "dashboard-stopped.png", screens / "dashboard-learner.png"])
    store = ParticipantStore.open(served.study, "P02")
    try:
        trials = store.rows("trials", order_by="trial_index")
        assert [(t.interaction, t.attempt, t.outcome.value) for t in trials] == [
            (1, 1, "aborted"), (1, 2, "aborted"), (1, 3, "completed"), (2, 1, "completed")]
        assert trials[0].reason == "aborted by the experimenter"
        assert trials[1].reason == "stopped by the experimenter (Stop)"
        placements = store.rows("placements")
        assert [(p.interaction, p.trial_index) for p in placements] == [(1, 3), (2, 4)]
        assert placements[0].position == pytest.approx(0.3, abs=0.01)
        assert placements[1].position == pytest.approx(0.9, abs=0.01)
        assert {(c.winner, c.loser) for c in store.rows("comparisons")} == {(2, 1)}
    finally:
        store.close()
