"""The simulated participant's answers to the questionnaire."""

from __future__ import annotations

import pytest

from app.protocol.simulated_participant import SimulatedParticipant
from session_store.vocabulary import question, question_ids


def test_answers_are_allowed_answers_of_each_question() -> None:
    participant = SimulatedParticipant(7)
    for question_id in question_ids():
        asked = question(question_id)
        assert asked is not None
        assert participant.answer(question_id, None) in asked.allowed()


def test_an_unknown_question_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"question_id = 'Q9' is not one of \['Q1'"):
        SimulatedParticipant(7).answer("Q9", None)
