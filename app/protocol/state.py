"""A participant's protocol state, rebuilt from the event log alone.

``apply(state, event)`` is the only place that moves the protocol forward, and the one place that
decides what an event may do: it dispatches each typed event (:mod:`app.protocol.events`) through
:data:`HANDLERS`, and each handler first checks that the state allows the event (a trial starts only
when the session is ready for it, see :data:`WAITS_FOR`; an interaction is completed once; a placement
is for the trial that waits for one, …). The engine applies each new event to a copy of its state
before committing it, a breach refusing the action (:class:`~app.protocol.errors.RefusedAction`), and
asks :func:`refusal` before an action builds its event; a resumed session folds the stored log through
the same function, so a resumed session cannot differ from one that never stopped, and a log that
breaks the protocol is reported as such (:class:`~app.protocol.errors.EventLogError`: event number,
what is wrong — an event no rule is written for included).
"""

from __future__ import annotations

from collections.abc import Callable
from enum import StrEnum
from typing import Any

from pydantic import BaseModel, Field

from app.protocol import events as ev
from app.protocol.errors import EventLogError
from app.protocol.plan import Rating, Slot
from robot_io.control.stages import Stage, StageName
from robot_io.theta import Theta
from session_store.models import Event, TrialOutcome
from session_store.vocabulary import Phase, ThetaOrigin, question, question_ids, questions


class Step(StrEnum):
    """What the session waits for."""

    PLAN = "plan"  # the learner is choosing the next θ
    READY = "ready"  # θ is planned: the experimenter may start the trial
    RUNNING = "running"  # a trial is running
    PLACE = "place"  # the participant places the last interaction on the scale
    HINT = "hint"  # the participant may hint which way the robot should change (coactive)
    RATE = "rate"  # the participant rates the last interaction against the previous one
    ANSWER = "answer"  # the questionnaire
    DONE = "done"


#: The steps that wait for the participant's answer (on the tablet, or the simulated participant's).
PARTICIPANT_STEPS = frozenset({Step.PLACE, Step.HINT, Step.RATE, Step.ANSWER})


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
    stage: StageName | None = None  # the running trial's stage of the handover cycle
    go_at: str | None = None  # UTC time of the running trial's Go
    simulated_participant: bool = False  # the simulated participant rates (switched by events)
    blind: bool | None = None  # the dashboard hides validation θ/origin; None: never recorded
    created: bool = False
    #: a coactive hint follows every placement ([protocol] coactive, from session_created)
    coactive: bool = False
    #: the last interaction learned from when learning stopped early (stop_when_settled), else None
    stopped_after: int | None = None
    #: the latest answer recorded as not used (two answers at once), until the next trial starts
    not_used: ev.EntryNotUsed | None = None
    last_event: int = 0

    @property
    def slot(self) -> Slot | None:
        return self.slots[self.cursor] if self.cursor < len(self.slots) else None

    @property
    def questionnaire_due(self) -> bool:
        """The questionnaire comes after the learning and best phases, before validation."""
        slot = self.slot
        at_validation = slot is None or slot.phase is Phase.VALIDATION
        return at_validation and len(self.answers) < len(questions())

    @property
    def unanswered(self) -> tuple[str, ...]:
        """The questions not answered yet, in the order they are asked."""
        return tuple(q for q in question_ids() if q not in self.answers)

    @property
    def step(self) -> Step:
        if self.running_trial is not None:
            return Step.RUNNING
        if self.awaiting is Rating.SCALE:
            return Step.PLACE
        if self.awaiting is Rating.HINT:
            return Step.HINT
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

    @property
    def interactions(self) -> int:
        """The interactions of the plan as it stands now: every slot but the learning ones an
        early stop skipped (``stop_when_settled``); 34 with the paper's counts and no stop."""
        if self.stopped_after is None:
            return len(self.slots)
        return sum(s.learner_index is None or s.interaction <= self.stopped_after
                   for s in self.slots)


def _advance(state: SessionState) -> None:
    previous = state.slots[state.cursor]
    state.cursor += 1
    state.awaiting = Rating.NONE
    new = state.slot
    if new is None or (new.phase, new.batch) != (previous.phase, previous.batch):
        state.markers = []  # the scale is cleared after every batch


class _Breach(Exception):
    """An event the state does not allow (wrapped into EventLogError by :func:`apply`)."""


def _check(condition: bool, problem: str) -> None:
    if not condition:
        raise _Breach(problem)


def _waiting_for(state: SessionState) -> str:
    return f"the session waits for '{state.step.value}'"


#: The step the session must wait for before each of these events may happen (its other rules are
#: its handler's): :func:`apply` checks every event against it, the engine's actions ask
#: :func:`refusal` before they build their event.
WAITS_FOR: dict[type, Step] = {
    ev.TrialStarted: Step.READY, ev.PlacementMade: Step.PLACE, ev.HintGiven: Step.HINT,
    ev.ValidationRated: Step.RATE, ev.AnswerGiven: Step.ANSWER,
}


def refusal(state: SessionState, kind: type) -> str | None:
    """Why an event of ``kind`` may not happen now (None: the session waits for it)."""
    wanted = WAITS_FOR.get(kind)
    if wanted is None or state.step is wanted:
        return None
    return f"the session waits for '{state.step.value}', not '{wanted.value}'"


def not_running(state: SessionState, trial_index: int) -> str | None:
    """Why a stage or the end of trial ``trial_index`` may not be recorded (None: it runs)."""
    if trial_index == state.running_trial:
        return None
    return f"trial {trial_index} is not running (running: {state.running_trial})"


def _in_step(state: SessionState, event: ev.ProtocolEvent, what: str) -> None:
    """``event`` (``what`` happens) only in the step :data:`WAITS_FOR` names."""
    _check(state.step is WAITS_FOR[type(event)], f"{what} while {_waiting_for(state)}")


def _created(state: SessionState, event: ev.SessionCreated) -> None:
    _check(not state.created, "the session is created twice")
    state.created = True
    state.coactive = bool(event.config.get("coactive", False))


def _theta_planned(state: SessionState, event: ev.ThetaPlanned) -> None:
    _check(event.interaction <= len(state.slots), f"plans interaction {event.interaction}; the "
                                                  f"protocol has {len(state.slots)}")
    _check(event.interaction not in state.planned, f"interaction {event.interaction} is planned "
                                                   "twice")
    state.planned[event.interaction] = PlannedTheta(
        theta=Theta(a=event.a, delta=event.delta, k=event.k), origin=event.origin,
        fallback=event.fallback)


def _learning_stopped(state: SessionState, event: ev.LearningStopped) -> None:
    slot = state.slot
    if not (state.step is Step.PLAN and slot is not None and slot.phase is Phase.LEARNING
            and slot.position == 1):
        raise _Breach(f"learning stops while {_waiting_for(state)}, not at the opening of a "
                      "learning batch")
    _check(event.after_interaction == slot.interaction - 1, f"learning stops after interaction "
                                                            f"{event.after_interaction}; the last "
                                                            f"one is {slot.interaction - 1}")
    state.cursor = next((i for i, s in enumerate(state.slots) if i > state.cursor
                         and s.learner_index is None), len(state.slots))
    state.markers = []
    state.stopped_after = event.after_interaction


def _learning_checked(state: SessionState, event: ev.LearningChecked) -> None:
    slot = state.slot
    _check(state.step is Step.PLAN and slot is not None
           and slot.interaction - 1 == event.after_interaction,
           f"the batch ending with interaction {event.after_interaction} is checked while "
           f"{_waiting_for(state)} at interaction {slot.interaction if slot else 'none'}")


def _trial_started(state: SessionState, event: ev.TrialStarted) -> None:
    slot = state.slot
    _check(state.running_trial is None, f"trial {event.trial_index} starts while trial "
                                        f"{state.running_trial} runs")
    _in_step(state, event, f"trial {event.trial_index} starts")
    _check(not state.paused, f"trial {event.trial_index} starts while the session is paused: "
                             "resume it first")
    assert slot is not None, "the session is READY only at a slot"
    _check(event.interaction == slot.interaction, f"trial {event.trial_index} is for interaction "
                                                  f"{event.interaction}; the session is at "
                                                  f"interaction {slot.interaction}")
    _check(event.trial_index == state.next_trial_index, f"trial_index {event.trial_index}; the "
                                                        f"next is {state.next_trial_index}")
    expected = state.attempts.get(event.interaction, 0) + 1
    _check(event.attempt == expected, f"attempt {event.attempt} of interaction "
                                      f"{event.interaction}; the next is {expected}")
    state.running_trial = event.trial_index
    state.not_used = None
    state.attempts[event.interaction] = event.attempt
    state.next_trial_index = event.trial_index + 1
    state.stage = state.go_at = None


def _trial_stage(state: SessionState, event: ev.TrialStage) -> None:
    _check((why := not_running(state, event.trial_index)) is None, f"stage {event.stage}: {why}")
    state.stage = event.stage
    if event.stage == Stage.GO:
        state.go_at = event.at


def _trial_ended(state: SessionState, event: ev.TrialEnded) -> None:
    _check((why := not_running(state, event.trial_index)) is None, f"end of {why}")
    state.running_trial = None
    state.stage = None
    if event.outcome is not TrialOutcome.COMPLETED:
        return
    slot = state.slots[state.cursor]
    earlier = state.completed_trial.get(slot.interaction)
    _check(earlier is None, f"interaction {slot.interaction} is completed twice (trials {earlier} "
                            f"and {event.trial_index})")
    state.completed_trial[slot.interaction] = event.trial_index
    rated = slot.rating is Rating.SCALE or (
        slot.rating is Rating.VALIDATION and slot.position == slot.batch_size)
    if rated:
        state.awaiting = slot.rating
    else:
        _advance(state)


def _about_the_completed(state: SessionState, what: str, event: ev.PlacementMade | ev.HintGiven
                         ) -> Slot:
    """Check that the session waits for ``event`` and that it is about the trial that completed
    the current interaction; that interaction's slot."""
    _in_step(state, event, f"{what} trial {event.trial_index}")
    slot = state.slots[state.cursor]
    completed = state.completed_trial.get(slot.interaction)
    _check(event.interaction == slot.interaction and event.trial_index == completed,
           f"{what} trial {event.trial_index} (interaction {event.interaction}); the session "
           f"waits for trial {completed} (interaction {slot.interaction})")
    return slot


def _placement_made(state: SessionState, event: ev.PlacementMade) -> None:
    slot = _about_the_completed(state, "a placement of", event)
    markers = {m.interaction for m in state.markers}
    _check(event.equal_to is None or event.equal_to in markers,
           f"equal_to = {event.equal_to} is not on the scale (on it: {sorted(markers)})")
    state.markers.append(Marker(interaction=slot.interaction, label=slot.position,
                                position=event.position, equal_to=event.equal_to))
    if state.coactive:
        state.awaiting = Rating.HINT
    else:
        _advance(state)


def _hint_given(state: SessionState, event: ev.HintGiven) -> None:
    _about_the_completed(state, "a hint about", event)
    _advance(state)


def _validation_rated(state: SessionState, event: ev.ValidationRated) -> None:
    _in_step(state, event, "a validation rating")
    slot = state.slots[state.cursor]
    _check(event.interaction == slot.interaction, f"rates interaction {event.interaction}; the "
                                                  f"session waits for {slot.interaction}")
    _advance(state)


def _answer_given(state: SessionState, event: ev.AnswerGiven) -> None:
    _in_step(state, event, f"an answer to {event.question}")
    asked = question(event.question)
    if asked is None:
        raise _Breach(f"question = {event.question!r} is not one of {question_ids()}")
    _check(event.question not in state.answers, f"{event.question} is already answered "
                                                f"({state.answers.get(event.question)!r})")
    _check(event.value in asked.allowed(), f"answer to {event.question} = {event.value!r} is "
                                           f"not one of {asked.allowed()}")
    state.answers[event.question] = event.value


def _not_used(state: SessionState, event: ev.EntryNotUsed) -> None:
    _check(event.counted_seq <= state.last_event, f"an answer not used in favour of event "
                                                  f"{event.counted_seq}, which is not stored before it")
    state.not_used = event


def _paused(state: SessionState, event: ev.Paused) -> None:
    _check(not state.paused, "the session is already paused")
    _check(state.running_trial is None, f"pause while trial {state.running_trial} runs: abort or "
                                        "finish it first")
    _check(state.step is not Step.DONE, "pause after the session is complete")
    state.paused = True


def _resumed(state: SessionState, event: ev.Resumed) -> None:
    _check(state.paused, "the session is not paused")
    state.paused = False


def _switched(state: SessionState, event: ev.SimulatedParticipantSwitched) -> None:
    state.simulated_participant = event.on


def _blinding_set(state: SessionState, event: ev.ValidationBlindingSet) -> None:
    state.blind = event.blind


def _recorded(state: SessionState, event: ev.ProtocolEvent) -> None:
    """Events that record what happened around the protocol without moving it."""


#: event type → the function that folds it into the state (and checks that the state allows it).
HANDLERS: dict[type, Callable[[SessionState, Any], None]] = {
    ev.SessionCreated: _created, ev.SessionResumed: _recorded, ev.ThetaPlanned: _theta_planned,
    ev.LearningChecked: _learning_checked, ev.LearningStopped: _learning_stopped,
    ev.TrialStarted: _trial_started, ev.TrialStage: _trial_stage, ev.TrialEnded: _trial_ended,
    ev.PlacementMade: _placement_made, ev.HintGiven: _hint_given,
    ev.ValidationRated: _validation_rated,
    ev.AnswerGiven: _answer_given, ev.EntryNotUsed: _not_used, ev.Paused: _paused, ev.Resumed: _resumed,
    ev.DevicesRecorded: _recorded, ev.RigChangeConfirmed: _recorded,
    ev.SimulatedParticipantSwitched: _switched, ev.ValidationBlindingSet: _blinding_set,
}


def apply(state: SessionState, event: ev.ProtocolEvent) -> SessionState:
    """Fold one event into the state. An event the state does not allow (the protocol's
    invariants) raises :class:`EventLogError` naming the event; the state is then unusable."""
    handler = HANDLERS.get(type(event))
    if handler is None:
        raise EventLogError(event.seq, event.kind, f"no rule of the protocol takes a "
                                                   f"{type(event).__name__} event")
    try:
        handler(state, event)
    except _Breach as breach:
        raise EventLogError(event.seq, event.kind, str(breach)) from None
    state.last_event = event.seq or state.last_event
    return state


def replay(slots: list[Slot], events: list[Event]) -> SessionState:
    """The state a stored log leads to; every event is validated (:func:`app.protocol.events.parse`)
    and checked against the state before it (:class:`EventLogError` at the first breach)."""
    state = SessionState(slots=slots)
    for row in events:
        apply(state, ev.parse(row))
    return state
