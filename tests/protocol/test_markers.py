"""The study's markers (app/protocol/markers.py) of the events a short recorded session does not
make (tests/session/test_lsl_outlets.py records every other kind), and of those that make none."""

from __future__ import annotations

from app.protocol import events as ev
from app.protocol.markers import decode, encode, marker
from session_store.vocabulary import Actor


def test_a_validation_rating_is_marked_with_its_interaction_and_who_rated():
    rated = ev.ValidationRated(seq=41, actor=Actor.PARTICIPANT, interaction=30, rating="better")
    content = marker(rated, state=None)
    assert content == {"event": "rating", "seq": 41, "interaction": 30, "rating": "better",
                       "by": "participant"}
    assert decode(encode(content)) == content


def test_events_outside_the_trials_and_ratings_make_no_marker():
    assert marker(ev.Paused(seq=3, actor=Actor.EXPERIMENTER, reason="a break"), state=None) is None
    assert marker(ev.Resumed(seq=4, actor=Actor.EXPERIMENTER), state=None) is None
