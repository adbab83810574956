"""A participant's protocol state, rebuilt from the event log alone.

``apply(state, event)`` is the only place that moves the protocol forward; the engine applies each
event right after committing it, and a resumed session folds the stored log through the same function,
so a resumed session cannot differ from one that never stopped.
"""

from __future__ import annotations

from enum import StrEnum

from pydantic import BaseModel, Field

from app.protocol.plan import Rating, Slot
from robot_io.stages import Stage
from robot_io.theta import Theta
from session_store.models import QUESTIONS, Event, Phase, ThetaOrigin


class Step(StrEnum):
    """What the session waits for."""

    PLAN = "plan"  # the learner is choosing the next θ
    READY = "ready"  # θ is planned: the experimenter may start the trial
    RUNNING = "running"  # a trial is running
    PLACE = "place"  # the participant places the last interaction on the scale
    RATE = "rate"  # the participant rates the last interaction against the previous one
    ANSWER = "answer"  # the questionnaire
    DONE = "done"


class PlannedTheta(BaseModel):
    theta: Theta
    origin: ThetaOrigin
    fallback: bool = False


class Marker(BaseModel):
    """An interaction of the current batch as it stands on the scale."""

    interaction: int
    label: int  # its number within the batch ("1" … "5" on the tablet)
    position: float
    equal_to: int | None = None


class SessionState(BaseModel):
    slots: list[Slot]
    cursor: int = 0  # index of the current slot
    planned: dict[int, PlannedTheta] = Field(default_factory=dict)
    attempts: dict[int, int] = Field(default_factory=dict)
    completed_trial: dict[int, int] = Field(default_factory=dict)  # interaction → trial_index
    running_trial: int | None = None
    next_trial_index: int = 1
    awaiting: Rating = Rating.NONE
    markers: list[Marker] = Field(default_factory=list)
    answers: dict[str, str] = Field(default_factory=dict)
    paused: bool = False
    stage: Stage | None = None  # the running trial's stage of the handover cycle
    go_at: str | None = None  # UTC time of the running trial's Go
    last_event: int = 0

    @property
    def slot(self) -> Slot | None:
        return self.slots[self.cursor] if self.cursor < len(self.slots) else None

    @property
    def questionnaire_due(self) -> bool:
        """Q1–Q3 come after the learning and best phases, before validation."""
        slot = self.slot
        at_validation = slot is None or slot.phase is Phase.VALIDATION
        return at_validation and len(self.answers) < len(QUESTIONS)

    @property
    def step(self) -> Step:
        if self.running_trial is not None:
            return Step.RUNNING
        if self.awaiting is Rating.SCALE:
            return Step.PLACE
        if self.awaiting is Rating.VALIDATION:
            return Step.RATE
        if self.questionnaire_due:
            return Step.ANSWER
        slot = self.slot
        if slot is None:
            return Step.DONE
        return Step.READY if slot.interaction in self.planned else Step.PLAN

    @property
    def phase(self) -> Phase:
        if self.step is Step.ANSWER:
            return Phase.QUESTIONNAIRE
        slot = self.slot
        if self.awaiting is not Rating.NONE:  # rating the interaction that just ended
            slot = self.slots[self.cursor]
        return Phase.DONE if slot is None else slot.phase

    @property
    def completed(self) -> int:
        return len(self.completed_trial)


def _advance(state: SessionState) -> None:
    previous = state.slots[state.cursor]
    state.cursor += 1
    state.awaiting = Rating.NONE
    new = state.slot
    if new is None or (new.phase, new.batch) != (previous.phase, previous.batch):
        state.markers = []  # the scale is cleared after every batch


def apply(state: SessionState, event: Event) -> SessionState:
    """Fold one stored event into the state (events are trusted: the engine validated them)."""
    p = event.payload
    kind = event.kind
    if kind == "theta_planned":
        state.planned[p["interaction"]] = PlannedTheta(
            theta=Theta(a=p["a"], delta=p["delta"], k=p["k"]), origin=ThetaOrigin(p["origin"]),
            fallback=p.get("fallback", False))
    elif kind == "trial_started":
        state.running_trial = p["trial_index"]
        state.attempts[p["interaction"]] = p["attempt"]
        state.next_trial_index = p["trial_index"] + 1
        state.stage = state.go_at = None
    elif kind == "trial_stage":
        state.stage = Stage(p["stage"])
        if state.stage is Stage.GO:
            state.go_at = event.at
    elif kind == "trial_ended":
        state.running_trial = None
        state.stage = None
        if p["outcome"] == "completed":
            slot = state.slots[state.cursor]
            state.completed_trial[slot.interaction] = p["trial_index"]
            rated = slot.rating is Rating.SCALE or (
                slot.rating is Rating.VALIDATION and slot.position == slot.batch_size)
            if rated:
                state.awaiting = slot.rating
            else:
                _advance(state)
    elif kind == "placement_made":
        slot = state.slots[state.cursor]
        state.markers.append(Marker(interaction=slot.interaction, label=slot.position,
                                    position=p["position"], equal_to=p.get("equal_to")))
        _advance(state)
    elif kind == "validation_rated":
        _advance(state)
    elif kind == "answer_given":
        state.answers[p["question"]] = p["value"]
    elif kind == "paused":
        state.paused = True
    elif kind == "resumed":
        state.paused = False
    state.last_event = event.seq or state.last_event
    return state


def replay(slots: list[Slot], events: list[Event]) -> SessionState:
    state = SessionState(slots=slots)
    for event in events:
        apply(state, event)
    return state
