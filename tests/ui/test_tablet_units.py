"""The tablet's pure parts: where the handle starts, the settle window, the questionnaire draft, the
screen each step shows."""

from __future__ import annotations

import re
from itertools import combinations

import pytest
from pydantic import ValidationError
from support.engine import study_config

from app.protocol.plan import Rating, protocol_slots
from app.protocol.state import Marker, SessionState, Step
from app.session.runner import RunnerView
from app.ui.deliberate import Settle
from app.ui.questionnaire import Draft
from app.ui.scale_view import APART, CLEARANCE, SNAP, render_scale, snap, start_position
from app.ui.tablet import HINTS, hint_of, screen_for
from session_store.vocabulary import Hint


def markers(*positions: float) -> list[Marker]:
    return [Marker(interaction=i, label=i, position=p) for i, p in enumerate(positions, start=1)]


@pytest.mark.parametrize("positions", [(), (0.2,), (0.5,), (0.5, 0.5), (0.45, 0.55, 0.9),
                                       (0.0, 0.25, 0.5, 0.75, 1.0), (0.48, 0.49, 0.5, 0.51)])
def test_the_handle_never_starts_on_a_marker(positions: tuple[float, ...]) -> None:
    start = start_position(markers(*positions))
    assert 0.0 <= start <= 1.0
    assert snap(start, markers(*positions)) is None  # an untouched handle is never "equal"
    assert all(abs(start - p) >= CLEARANCE - 1e-9 for p in positions)


def test_the_handle_starts_in_the_widest_gap_when_the_centre_is_taken() -> None:
    assert start_position(markers(0.2)) == 0.5  # centre free
    assert start_position(markers(0.5, 0.9)) == 0.25  # [0, 0.5] is the widest gap
    assert start_position(markers(0.1, 0.52)) == 0.76  # [0.52, 1]
    assert SNAP < CLEARANCE


def test_settle_ignores_input_for_the_window_after_each_screen() -> None:
    now = [10.0]
    settle = Settle(0.4, clock=lambda: now[0])
    assert not settle.ready()
    now[0] = 10.399
    assert not settle.ready()
    now[0] = 10.4
    assert settle.ready()
    settle.restart()
    now[0] = 10.7
    assert not settle.ready()
    with pytest.raises(ValueError, match="settle_s = 9"):
        Settle(9)


def test_the_questionnaire_draft_moves_back_and_next_and_completes_once_all_are_chosen() -> None:
    draft = Draft(questions=("Q1", "Q2", "Q3"))
    assert (draft.question, draft.number, draft.first) == ("Q1", 1, True)
    assert draft.next() == draft  # no choice yet: Next does not move
    draft = draft.choose("4").next()
    assert (draft.question, draft.number, draft.choice) == ("Q2", 2, None)
    assert draft.back().choice == "4"  # Back shows the earlier choice, still changeable
    draft = draft.back().choose("2").next().choose("Maybe").next().choose("5")
    assert draft.last and draft.next() == draft
    assert draft.complete() == [("Q1", "2"), ("Q2", "Maybe"), ("Q3", "5")]
    assert Draft(questions=("Q1", "Q2")).choose("1").complete() == []


def test_a_partly_stored_questionnaire_continues_with_the_rest() -> None:
    draft = Draft(questions=("Q3",))
    assert (draft.number, draft.first, draft.last) == (3, True, True)
    with pytest.raises(ValidationError, match="Q9"):
        Draft(questions=("Q9",))


def drawn(html: str) -> dict[str, tuple[float, int]]:
    """Each marker's label: its position (left, %) and its level, from the scale's HTML."""
    return {label: (float(left), int(level)) for left, level, label in re.findall(
        r'left:([\d.]+)%;--hl-level:(\d+)">(\d+)<', html)}


@pytest.mark.parametrize(("positions", "newest"), [
    ((0.30, 0.34, 1.0), 0.97), ((0.30, 0.34), 0.32), ((0.5, 0.5, 0.55), 0.45),
    ((0.1, 0.15, 0.2, 0.25), 0.6), ((0.30, 0.34), 0.30)])
def test_markers_closer_than_apart_stand_at_different_levels(positions, newest) -> None:
    shown = drawn(render_scale(markers(*positions), len(positions) + 1, newest))
    assert len(shown) == len(positions) + 1
    for (a, (left_a, level_a)), (b, (left_b, level_b)) in combinations(shown.items(), 2):
        if abs(left_a - left_b) < 100 * APART:
            assert level_a != level_b, f"{a} and {b} overlap: {shown}"


def test_equal_markers_stack_and_far_ones_stay_on_the_arrow() -> None:
    shown = drawn(render_scale(markers(0.2, 0.2, 0.8), 4, 0.8))  # the newest snaps to 3
    assert shown == {"1": (20.0, 0), "2": (20.0, 1), "3": (80.0, 0), "4": (80.0, 1)}


def test_a_coactive_hint_is_asked_on_its_own_screen_unless_the_simulated_participant_answers() -> None:
    """[protocol] coactive: after a placement the session waits at Step.HINT; the tablet asks about
    the handover just placed, or says "Please wait" while the simulated participant answers."""
    slots = protocol_slots(study_config(coactive=True, initial_trials=2, batch_size=2,
                                        learning_batches=1, validation_batches=0))
    state = SessionState(slots=slots, cursor=1, coactive=True, awaiting=Rating.HINT,
                         completed_trial={1: 1, 2: 2})
    assert state.step is Step.HINT
    view = RunnerView(code="P01", state=state)
    assert (screen_for(view).kind, screen_for(view).interaction) == ("hint", 2)
    assert screen_for(view.model_copy(update={"auto": True})).kind == "wait"


def test_every_hint_has_its_words_and_one_choice_means_nothing_to_change() -> None:
    assert [hint_of(value) for _, value in HINTS] == [*Hint, None]
    assert len({text for text, _ in HINTS}) == len(HINTS)
