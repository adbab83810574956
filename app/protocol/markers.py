"""The study's event markers: what the marker stream says of a stored protocol event (issue 24).

A marker is one JSON object per event the study decides and stores: a trial's start (with its θ and
where θ came from), each stage of its handover cycle (``go``, ``reach``, ``hold``, ``release``, …),
its end (with its safety record: app/protocol/safety_record.py), the placement confirmed on the
scale, the validation rating and each questionnaire answer. ``seq`` is the event's number in the
participant's events table, so a marker and its SQLite row are joined on it; ``trial`` is the trial
index. Events of other kinds (the session's creation, θ planned, pauses, device records) make no
marker.
"""

from __future__ import annotations

import json
from typing import Any

from app.protocol import events as ev
from app.protocol.state import SessionState

#: The study's streams (app/session/lsl_outlets.py): the ``software`` their descriptions name, the
#: marker stream's type (LSL's usual one) and the robot stream's.
SOFTWARE, MARKER_TYPE, ROBOT_TYPE = "handover-lab", "Markers", "HandoverRobot"
#: The kinds of stored event that make a marker, and the marker's ``event`` for each (a stage's
#: marker is named after the stage).
MARKED = {"trial_started": "trial_start", "trial_stage": None, "trial_ended": "trial_end",
          "placement_made": "placement_confirmed", "validation_rated": "rating",
          "answer_given": "answer"}


def marker(event: ev.ProtocolEvent, state: SessionState) -> dict[str, Any] | None:
    """The marker of a stored ``event`` (its ``seq`` set) in the ``state`` it led to; None for an
    event of a kind that is not marked."""
    common = {"seq": event.seq}
    match event:
        case ev.TrialStarted():
            planned = state.planned[event.interaction]
            return {"event": MARKED[event.kind], **common, "trial": event.trial_index,
                    "interaction": event.interaction, "attempt": event.attempt,
                    "theta": planned.theta.model_dump(), "origin": planned.origin.value}
        case ev.TrialStage():
            return {"event": event.stage, **common, "trial": event.trial_index, "t": event.t}
        case ev.TrialEnded():
            safety = None if event.safety is None else event.safety.model_dump()
            return {"event": MARKED[event.kind], **common, "trial": event.trial_index,
                    "outcome": event.outcome.value, "reason": event.reason, "safety": safety}
        case ev.PlacementMade():
            return {"event": MARKED[event.kind], **common, "trial": event.trial_index,
                    "interaction": event.interaction, "position": event.position,
                    "equal_to": event.equal_to, "by": event.actor.value}
        case ev.ValidationRated():
            return {"event": MARKED[event.kind], **common, "interaction": event.interaction,
                    "rating": event.rating, "by": event.actor.value}
        case ev.AnswerGiven():
            return {"event": MARKED[event.kind], **common, "question": event.question,
                    "value": event.value, "by": event.actor.value}
    return None


def encode(content: dict[str, Any]) -> str:
    """A marker as the marker stream's one string channel carries it."""
    return json.dumps(content, separators=(",", ":"), ensure_ascii=False)


def decode(text: str) -> dict[str, Any]:
    """A marker read back from a recording."""
    return json.loads(text)
