"""An answer for the participant, wherever it comes from — the tablet (the participant), the
dashboard's "Enter for the participant" (the experimenter on their behalf) or the simulated
participant — and what happens when two arrive for the same prompt (issue 45).

**Two answers at once** (docs/protocol.md): the answer stored first counts. The session engine
takes actions one at a time, so of two answers given at the same moment one is stored first; the
learner is taught it at once and the session moves on, so it is never taken back. The other is not
dropped without a word: when it comes from someone else (the participant's on the tablet after the
experimenter's on the dashboard, or the reverse) it is stored as an ``entry_not_used`` event — who,
what it said, and the answer that counts instead — the dashboard shows it until the next trial
starts, and the report lists it. A second answer by the same person is a double tap: refused,
nothing stored.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, model_validator

from app.protocol import events as ev
from app.protocol.engine import SessionEngine
from app.protocol.errors import RefusedAction
from app.protocol.state import SessionState, Step
from session_store.vocabulary import Actor, Hint, Rater

EntryKind = Literal["placement", "hint", "rating", "answer"]
#: What the session waits for when it takes each kind of answer.
STEP_OF: dict[EntryKind, Step] = {"placement": Step.PLACE, "hint": Step.HINT, "rating": Step.RATE,
                                  "answer": Step.ANSWER}
#: The event that stores each kind of answer.
EVENT_OF: dict[EntryKind, str] = {"placement": "placement_made", "hint": "hint_given",
                                  "rating": "validation_rated", "answer": "answer_given"}
WHO = {Actor.PARTICIPANT: "participant", Actor.EXPERIMENTER: "experimenter",
       Actor.SIMULATED_PARTICIPANT: "simulated participant"}
RATING_WORDS = {"better": "better", "worse": "worse", "equal": "the same"}


class Entry(BaseModel):
    """One answer for the participant: what kind, about which handover (``interaction``) or
    question, what it says, and by whom."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: EntryKind
    by: Rater
    interaction: int | None = None  # placement, hint, rating
    question: str | None = None  # answer
    position: float | None = None  # placement: on the scale …
    equal_to: int | None = None  # … or the same as an earlier handover of the batch
    hint: Hint | None = None  # hint (None: nothing to change)
    rating: str | None = None  # rating: better, worse, equal
    value: str | None = None  # answer

    @model_validator(mode="after")
    def _about_something(self) -> Entry:
        if (self.kind == "answer") != (self.question is not None) or \
                (self.kind != "answer") != (self.interaction is not None):
            raise ValueError(f"a {self.kind} names " + ("its question" if self.kind == "answer"
                                                         else "its interaction"))
        return self

    def payload(self) -> dict[str, Any]:
        """What it says, as the event that would store it says it."""
        return self.model_dump(include={"position", "equal_to", "hint", "rating", "value"},
                               mode="json")


def says(kind: EntryKind, payload: dict[str, Any]) -> str:
    """What an answer of ``kind`` says, in words ("at 0.42", "the same as handover 2", "sooner",
    "nothing to change", "the same", "4")."""
    if kind == "placement":
        return (f"the same as handover {payload['equal_to']}" if payload.get("equal_to")
                is not None else f"at {payload['position']:.2f}")
    if kind == "hint":
        return payload.get("hint") or "nothing to change"
    if kind == "rating":
        return RATING_WORDS[payload["rating"]]
    return str(payload["value"])


def _about(kind: EntryKind, interaction: int | None, question: str | None) -> str:
    return {"placement": f"placement of handover {interaction}",
            "hint": f"hint about handover {interaction}",
            "rating": f"rating of handover {interaction}",
            "answer": f"answer to {question}"}[kind]


def not_used_words(event: ev.EntryNotUsed) -> str:
    """The experimenter's line about an answer not used, e.g. "Not used: the participant's hint
    about handover 1 (sooner) came after the experimenter's (later), which counts"."""
    return (f"Not used: the {WHO[event.actor]}'s "
            f"{_about(event.entry, event.interaction, event.question)} ({event.value}) came after "
            f"the {WHO[event.counted_actor]}'s ({event.counted_value}), which counts")


class EntryNotUsed(RefusedAction):
    """An answer came after another for the same prompt and was recorded as not used."""

    def __init__(self, event: ev.EntryNotUsed) -> None:
        super().__init__(not_used_words(event))
        self.event = event


def _waiting(state: SessionState, entry: Entry) -> bool:
    """Whether the session waits for ``entry`` now."""
    if entry.kind == "answer":
        return state.step is Step.ANSWER and entry.question not in state.answers
    slot = state.slot
    return state.step is STEP_OF[entry.kind] and slot is not None and \
        slot.interaction == entry.interaction


def _take(engine: SessionEngine, entry: Entry) -> None:
    if entry.kind == "placement":
        engine.place(position=entry.position, equal_to=entry.equal_to, by=entry.by)
    elif entry.kind == "hint":
        engine.hint(entry.hint, by=entry.by)
    elif entry.kind == "rating":
        assert entry.rating is not None, "a rating says better, worse or equal"
        engine.rate_validation(entry.rating, by=entry.by)
    else:
        assert entry.question is not None and entry.value is not None, "an answer says its value"
        engine.answer(entry.question, entry.value, by=entry.by)


def enter(engine: SessionEngine, entry: Entry) -> None:
    """Take ``entry`` if the session waits for it. If its prompt was answered already by someone
    else, record it as not used and raise :class:`EntryNotUsed`; otherwise (a double tap, a stale
    screen) refuse it with the reason, storing nothing."""
    if _waiting(engine.state, entry):
        _take(engine, entry)
        return
    key = "question" if entry.kind == "answer" else "interaction"
    about = entry.question if entry.kind == "answer" else entry.interaction
    stored = next((e for e in reversed(engine.store.events()) if e.kind == EVENT_OF[entry.kind]
                   and e.payload.get(key) == about), None)
    if stored is None or stored.seq is None or stored.actor is entry.by.actor:
        what = ((f"{entry.question} is already answered" if stored is not None
                 else "the questionnaire is not due") if entry.kind == "answer"
                else f"interaction {entry.interaction} is not waiting for "
                     f"'{STEP_OF[entry.kind].value}'")
        raise RefusedAction(f"refused: {what} (the session waits for "
                            f"'{engine.state.step.value}')")
    event = ev.EntryNotUsed(actor=entry.by.actor, entry=entry.kind,
                            interaction=entry.interaction, question=entry.question,
                            value=says(entry.kind, entry.payload()), counted_seq=stored.seq,
                            counted_actor=stored.actor,
                            counted_value=says(entry.kind, stored.payload))
    engine.record_not_used(event)
    raise EntryNotUsed(event)
