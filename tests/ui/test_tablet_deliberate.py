"""Deliberate answers on the tablet, with touch in Chromium (issue 13).

A double tap stores one answer on every answer screen (scale, questionnaire, validation rating);
Confirm does nothing before the handle has moved, and the screen says so; a new handover never
starts as "equal"; Back revisits a question with its choice, and Next the question after it with
its own. What counts is what the store holds afterwards. (That input
inside the settle window after a screen change is ignored is tested in test_tablet_pages.py, with a
window long enough not to depend on the machine's load.)
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import (
    button,
    chromium,
    double_tap,
    open_participant,
    open_screens,
    run_trial,
    scale_value,
    serve,
    settle,
    shot,
    tablet_screen,
    tap,
    touch_drag_to,
    wait_enabled,
    wait_gone,
    wait_text,
)

from app.ui.scale_view import SNAP
from app.ui.tablet import MOVE_FIRST
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

SHOTS = Path("/tmp/tablet-shots")

#: Two placed handovers, the best one, the questionnaire, one validation pair.
PROTOCOL = ("initial_trials = 2\nbatch_size = 2\nlearning_batches = 0\nwithout_learning = true\n"
            "best_trials = 1\n"
            "validation_batches = 1\n")


def test_double_taps_store_one_answer_and_confirm_needs_a_move(tmp_path: Path) -> None:
    """Slow: a whole brief session by touch, on the wall clock: two placed handovers, the learned
    best, the three questions and a validation pair; the pauses between taps (``settle``) let each
    tap be a separate gesture, as a participant's are."""
    with serve(tmp_path, protocol_toml=PROTOCOL) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        open_participant(dashboard, "P01")

        # Handover 1: the handle starts at the centre; Confirm is disabled until it moves, and the
        # screen says so (issue 45, item 14: one who left the handle there had no hint).
        assert run_trial(dashboard, tablet) == "place"
        settle()
        assert button(tablet, "Confirm").is_disabled()
        wait_text(tablet, MOVE_FIRST)
        shot(tablet, SHOTS, "place-confirm-waits-for-a-move")
        touch_drag_to(tablet, 0.2)
        touch_drag_to(tablet, 0.5)
        wait_gone(tablet, MOVE_FIRST)
        double_tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="place") == "wait"

        # Handover 2: marker 1 stands at the centre, so the handle starts elsewhere: an untouched
        # handle never means "equal", and Confirm before any drag stores nothing.
        assert run_trial(dashboard, tablet) == "place"
        settle()
        start = scale_value(tablet)
        assert abs(start - 0.5) > SNAP and "Same as" not in tablet.inner_text("body")
        tap(tablet, "Confirm", enabled=False)
        settle()
        assert tablet_screen(tablet) == "place" and button(tablet, "Confirm").is_disabled()
        touch_drag_to(tablet, 0.8)
        double_tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="place") == "wait"

        # The best handover, then the questionnaire, one question per screen.
        assert run_trial(dashboard, tablet) == "Q1"
        body = tablet.inner_text("body")
        assert "Question 1 of 3" in body and button(tablet, "‹ Back").count() == 0
        settle()
        tap(tablet, "4")
        double_tap(tablet, "Next")  # the second tap lands on Q2's Next: still disabled there
        assert tablet_screen(tablet, not_="Q1") == "Q2"
        assert "Question 2 of 3" in tablet.inner_text("body")
        assert button(tablet, "Next").is_disabled()  # nothing chosen on Q2 yet
        settle()
        tap(tablet, "‹ Back")
        assert tablet_screen(tablet, not_="Q2") == "Q1"
        assert not button(tablet, "Next").is_disabled()  # Q1 keeps its "4"
        settle()
        tap(tablet, "Next")
        assert tablet_screen(tablet, not_="Q1") == "Q2"
        settle()
        tap(tablet, "Maybe")
        # the choice taken (Next enabled) before Back: a tap while the server still handles the
        # page's previous input is dropped by design (app/ui/tablet.py _input), as a loaded run
        # showed (Back 50 ms after Maybe, ignored)
        wait_enabled(tablet, "Next")
        # Back and Next again: Q2 keeps its "Maybe" (issue 45, item 13: it came back empty)
        tap(tablet, "‹ Back")
        assert tablet_screen(tablet, not_="Q2") == "Q1"
        settle()
        tap(tablet, "Next")
        assert tablet_screen(tablet, not_="Q1") == "Q2"
        assert not button(tablet, "Next").is_disabled()
        shot(tablet, SHOTS, "questionnaire-q2-kept")
        settle()
        tap(tablet, "Next")
        assert tablet_screen(tablet, not_="Q2") == "Q3"
        settle()
        tap(tablet, "5 – Perfectly")
        double_tap(tablet, "Done")
        assert tablet_screen(tablet, not_="Q3") == "pairs"

        # The validation pair: choose, then Confirm (double-tapped).
        assert run_trial(dashboard, tablet) == "wait"
        assert "second handover of this pair" in tablet.inner_text("body")
        assert run_trial(dashboard, tablet) == "rate"
        settle()
        assert button(tablet, "Confirm").is_disabled()
        tap(tablet, "Worse")
        tap(tablet, "Better")  # a changed mind: the last choice counts
        double_tap(tablet, "Confirm")
        assert tablet_screen(tablet, not_="rate") == "done"
        served.shutdown()

    store = ParticipantStore.open(served.study, "P01")
    try:
        placements = store.rows("placements")
        assert [(p.interaction, p.equal_to) for p in placements] == [(1, None), (2, None)]
        assert placements[0].position == pytest.approx(0.5, abs=0.01)
        assert placements[1].position == pytest.approx(0.8, abs=0.01)  # not the untouched start
        answers = store.rows("answers")
        assert [(a.question, a.value) for a in answers] == [("Q1", "4"), ("Q2", "Maybe"),
                                                            ("Q3", "5")]
        assert [(r.interaction, r.rating) for r in store.rows("validation_ratings")] == [
            (5, "better")]
    finally:
        store.close()
