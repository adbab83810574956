"""A whole participant session on the tablet with touch, against the store (moved here from
tests/test_ui_browser.py).

`handover serve` in a subprocess, the tablet and the dashboard in headless Chromium. The
participant's placements are real touch drags; what the store holds afterwards is checked against
what was dragged. Screenshots go to the test's tmp folder (and, with HANDOVER_DOC_FIGURES=1, to
docs/figures/ for docs/running-a-study.md).
"""

from __future__ import annotations

import statistics
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    Served,
    answer_questionnaire,
    chromium,
    click,
    confirm_placement,
    open_participant,
    open_screens,
    publish,
    rate,
    scale_value,
    serve,
    shot,
    tablet_screen,
    touch_drag_to,
    wait_function,
    wait_text,
)

from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Where the participant drags each interaction: a fraction of the scale, or ("equal", label).
DRAGS: dict[int, float | tuple[str, int]] = {1: 0.6, 2: 0.25, 3: 0.8, 4: 0.4, 5: 0.7,
                                             6: ("equal", 1)}
ANSWERS = {"Q1": "4", "Q2": "Maybe", "Q3": "5 – Perfectly"}


def place_by_touch(tablet: Page, interaction: int, positions: dict[int, float],
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


def wait_stage(dashboard: Page) -> None:
    """Wait until the dashboard shows the trial's stage from Go on (its live view drawing), or the
    trial's end: a ~6 s trial can be over before a loaded browser drew any of its stages, and the
    stage line goes when the trial ends."""
    wait_function(dashboard, "s => s.some(t => document.body.innerText.includes(t))",
                  "the dashboard showing the trial from Go on, or its end",
                  arg=["[go]", "[reach]", "[hold]", "[release]", "[retract]", "[done]",
                       "trial 1 completed"])


def test_participant_session_with_touch(tmp_path: Path) -> None:
    """Slow (about 90 s alone): a whole session by touch in Chromium, every trial on the wall clock
    and every learner fit in the learner process."""
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
            screen = tablet_screen(tablet, not_=("go", "back"))
            if screen in ("wait", "pairs"):
                if screen == "pairs":
                    shot(tablet, screens, "tablet-pairs")
                for name in ("Start trial", "Object loaded", "Go"):
                    click(dashboard, name)
                interaction += 1
                assert tablet_screen(tablet, not_=screen) in ("go", "place", "rate", "Q1")
                if "go" not in shown:
                    assert tablet.locator("audio.hl-cue").count() == 1  # the audible cue
                    wait_function(tablet, "() => { const a = document.querySelector('audio.hl-cue');"
                                          " return a && (!a.paused || a.ended); }",
                                  "the cue playing (or played) without a tap")
                    shot(tablet, screens, "tablet-go")
                    wait_stage(dashboard)  # the trial under way on the dashboard, for its shot
                    shot(dashboard, screens, "dashboard-trial")
                    shown.add("go")
                continue
            if screen == "place":
                label = int(tablet.inner_text("body").split("Handover ")[1].split()[0])
                if label == 1:
                    batch_labels.clear()
                batch_labels[label] = interaction
                dragged[interaction] = place_by_touch(tablet, interaction, positions,
                                                      batch_labels)
                positions[interaction] = dragged[interaction][0] or positions[
                    dragged[interaction][1]]
                shot(tablet, screens, f"tablet-place-{interaction}")
                latencies.append(confirm_placement(tablet))
            elif screen == "Q1":
                shot(tablet, screens, "tablet-Q1")
                latencies.append(answer_questionnaire(tablet, ANSWERS))
            elif screen == "rate":
                latencies.append(rate(tablet, "Better", screens))
            elif screen == "done":
                shot(tablet, screens, "tablet-done")
                break
        output = served.shutdown()
    assert "stopping the arm" in output and "closed" in output
    publish([screens / f"{n}.png" for n in ("tablet-go", "tablet-place-6", "tablet-Q1",
                                            "tablet-rate", "tablet-pairs", "dashboard-trial")])
    print(f"confirmed → next screen: median {statistics.median(latencies) * 1e3:.0f} ms "
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
