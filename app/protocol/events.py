"""The protocol's events, typed: one pydantic model per kind, a discriminated union on ``kind``.

The store keeps every event as an envelope (``seq``, ``at``, ``actor``, ``kind``) and a JSON payload
(:class:`session_store.models.Event`); :func:`parse` turns a stored row into its typed event and
raises :class:`~app.protocol.errors.EventLogError` (event number, what is wrong) for a row that does
not parse, :func:`to_row` does the reverse. The state machine that folds them is
:mod:`app.protocol.state`.
"""

from __future__ import annotations

import typing
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from app.protocol.errors import EventLogError
from robot_io.control.stages import StageName
from session_store.models import Event, SafetyRecord, TrialOutcome, utc_now
from session_store.vocabulary import Actor, Hint, Rater, ThetaOrigin

#: The envelope's fields: stored as columns of the events table, not in the payload.
ENVELOPE = frozenset({"seq", "at", "actor", "kind"})


class _Event(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", populate_by_name=True)

    seq: int | None = Field(None, description="position in the log, 1…; None until stored")
    at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time")
    actor: Actor


class _Rated(_Event):
    """An event made by whoever rates: the participant, the simulated participant or the
    experimenter on the participant's behalf — never the system or the learner."""

    @model_validator(mode="after")
    def _by_a_rater(self) -> _Rated:
        if self.actor.value not in {r.value for r in Rater}:
            raise ValueError(f"actor = {self.actor.value!r} cannot rate: one of "
                             f"{[r.value for r in Rater]}")
        return self


class SessionCreated(_Event):
    kind: Literal["session_created"] = "session_created"
    code: str
    config: dict[str, Any]
    prior: dict[str, Any] | None = Field(None, description="the GP prior mean from earlier "
                                         "participants (population_prior), fixed at creation")


class SessionResumed(_Event):
    kind: Literal["session_resumed"] = "session_resumed"
    step: str = Field(description="what the session waited for when it was reopened")


class ThetaPlanned(_Event):
    kind: Literal["theta_planned"] = "theta_planned"
    interaction: int = Field(ge=1)
    a: float
    delta: float
    k: float
    origin: ThetaOrigin
    fallback: bool = Field(False, description="the learner was late: a Sobol point was used")
    fit_failed: bool = Field(False, description="the learner's last fit failed")


class LearningChecked(_Event):
    """After a batch of a session with a stopping rule (``stop_when_settled``,
    ``stop_when_no_gain``): the rule's signal, and whether learning stops (then a
    :class:`LearningStopped` follows in the same transaction)."""

    kind: Literal["learning_checked"] = "learning_checked"
    after_interaction: int = Field(ge=1, description="the last interaction of the batch")
    batches: int = Field(ge=0, description="learning batches run (0: after the initial batch)")
    rule: Literal["settled", "gain"] = Field(description="which rule: stop_when_settled or "
                                             "stop_when_no_gain")
    signal: float = Field(ge=0.0, le=1.0, description="settled: P(θ* within epsilon of the best "
                          "θ); gain: the chance that the next batch shows a handover preferred "
                          "to θ* more than the rule's preference (its bound (q − 1)·gain/epsilon)")
    gain: float | None = Field(None, ge=0.0, description="gain: what the next batch is expected "
                               "to add to θ*'s utility, max over θ of E[(u(θ) − u(θ*))⁺]")
    epsilon: float = Field(gt=0.0, description="the utility difference of the rule's preference")
    stops: bool = Field(description="learning stops here")


class LearningStopped(_Event):
    """Learning ended early (``stop_when_settled``, ``stop_when_no_gain``): the session goes on to
    the best interaction, the questionnaire and validation."""

    kind: Literal["learning_stopped"] = "learning_stopped"
    after_interaction: int = Field(ge=1, description="the last interaction that was learned from")
    batches: int = Field(ge=1, description="learning batches run")
    rule: Literal["settled", "gain"] = Field("settled", description="which rule stopped it")
    probability: float = Field(ge=0.0, le=1.0, description="the stopping signal (settled: P(θ* is "
                               "within epsilon of the best θ); gain: the chance that the next "
                               "batch finds a handover preferred to θ* by more than epsilon)")
    epsilon: float = Field(gt=0.0)
    threshold: float = Field(ge=0.0, le=1.0, description="settled: stops at this probability or "
                             "more; gain: at this chance or less")
    min_batches: int = Field(ge=1)
    reason: str = Field(description="why, in words")


class TrialStarted(_Event):
    kind: Literal["trial_started"] = "trial_started"
    trial_index: int = Field(ge=1)
    interaction: int = Field(ge=1)
    attempt: int = Field(ge=1)


class TrialStage(_Event):
    kind: Literal["trial_stage"] = "trial_stage"
    trial_index: int = Field(ge=1)
    stage: StageName = Field(description="a stage of the handover cycle (robot_io.control.stages); "
                                         "a stored one the cycle no longer has is still read")
    t: float | None = Field(description="seconds after Go (None before Go)")


class TrialEnded(_Event):
    kind: Literal["trial_ended"] = "trial_ended"
    trial_index: int = Field(ge=1)
    outcome: TrialOutcome
    reason: str | None = None
    #: the trial's safety record from its samples (app/protocol/safety_record.py); None for a trial
    #: that ended without samples, and in logs written before it existed
    safety: SafetyRecord | None = None


class PlacementMade(_Rated):
    kind: Literal["placement_made"] = "placement_made"
    trial_index: int = Field(ge=1)
    interaction: int = Field(ge=1)
    position: float = Field(ge=0.0, le=1.0)
    equal_to: int | None = None
    comparisons: list[tuple[int, int]] = Field(description="[winner, loser] pairs it implies")


class HintGiven(_Rated):
    """A coactive hint after a placement (``[protocol] coactive``): which way the robot should
    change (``hint``), or nothing (None); ``hinted`` is θ', the handover's θ moved that way, which
    the learner takes as preferred to it (None without a hint, or when θ stood at that edge)."""

    kind: Literal["hint_given"] = "hint_given"
    trial_index: int = Field(ge=1)
    interaction: int = Field(ge=1)
    hint: Hint | None
    hinted: dict[str, float] | None = Field(description="θ' as {a, delta, k}")


class ValidationRated(_Rated):
    kind: Literal["validation_rated"] = "validation_rated"
    interaction: int = Field(ge=1)
    rating: Literal["better", "worse", "equal"]


class AnswerGiven(_Rated):
    kind: Literal["answer_given"] = "answer_given"
    question: str
    value: str


class EntryNotUsed(_Rated):
    """An answer for the participant that came after another one for the same handover or question
    had been stored — the tablet and the dashboard at once (docs/protocol.md, "Two answers at
    once"): recorded, not used; the one stored first (``counted_seq``) counts."""

    kind: Literal["entry_not_used"] = "entry_not_used"
    entry: Literal["placement", "hint", "rating", "answer"] = Field(description="what it was")
    interaction: int | None = Field(None, ge=1, description="the handover it was about (placement, "
                                    "hint, rating)")
    question: str | None = Field(None, description="the question it answered (answer)")
    value: str = Field(description="what it said, in words")
    counted_seq: int = Field(ge=1, description="the event of the answer that counts")
    counted_actor: Actor = Field(description="who gave the answer that counts")
    counted_value: str = Field(description="what that answer said, in words")


class Paused(_Event):
    kind: Literal["paused"] = "paused"
    reason: str = ""


class Resumed(_Event):
    kind: Literal["resumed"] = "resumed"
    reason: str = ""


class DevicesRecorded(_Event):
    kind: Literal["devices_recorded"] = "devices_recorded"
    config: dict[str, Any] = Field(description="the configuration the trials use")
    devices: dict[str, Any] = Field(description="the devices actually opened")
    rig: dict[str, Any] | None = Field(None, description="the rig tables a resume compares (a "
                                       "rehearsal's per-run addresses read 'rehearsal'); None in "
                                       "files written before it was recorded")


class RigChangeConfirmed(_Event):
    kind: Literal["rig_change_confirmed"] = "rig_change_confirmed"
    previous: dict[str, Any] = Field(alias="from", description="the rig recorded before")
    to: dict[str, Any] = Field(description="the rig the session continues on")


class SimulatedParticipantSwitched(_Event):
    kind: Literal["simulated_participant_switched"] = "simulated_participant_switched"
    on: bool = Field(description="the simulated participant rates from now on (True) or the "
                                 "participant does (False)")


class ValidationBlindingSet(_Event):
    kind: Literal["validation_blinding_set"] = "validation_blinding_set"
    blind: bool = Field(description="the dashboard hides the θ and origin of validation trials "
                                    "(True, the default: the paper's blind validation, Sect. V-C) "
                                    "or shows them (False: serve --unblind, pilots and debugging)")


ProtocolEvent = Annotated[
    SessionCreated | SessionResumed | ThetaPlanned | LearningChecked | LearningStopped
    | TrialStarted | TrialStage | TrialEnded
    | PlacementMade | HintGiven | ValidationRated | AnswerGiven | EntryNotUsed | Paused | Resumed
    | DevicesRecorded
    | RigChangeConfirmed | SimulatedParticipantSwitched | ValidationBlindingSet,
    Field(discriminator="kind")]
_ADAPTER: TypeAdapter[ProtocolEvent] = TypeAdapter(ProtocolEvent)
#: Every kind of event, in the order of the union (docs/data.md lists them).
KINDS: tuple[str, ...] = tuple(model.model_fields["kind"].default
                               for model in typing.get_args(typing.get_args(ProtocolEvent)[0]))


def _problem(error: ValidationError) -> str:
    parts = []
    for item in error.errors():
        where = ".".join(str(p) for p in item["loc"][1:]) or "kind"
        parts.append(f"{where}: {item['msg']}")
    return "; ".join(parts)


def parse(row: Event) -> ProtocolEvent:
    """The typed event of a stored row; :class:`EventLogError` if it is not a valid event."""
    if row.kind not in KINDS:
        raise EventLogError(row.seq, row.kind, f"unknown kind of event (known: {', '.join(KINDS)})")
    clash = ENVELOPE & set(row.payload)
    if clash:
        raise EventLogError(row.seq, row.kind, f"payload repeats envelope fields {sorted(clash)}")
    try:
        return _ADAPTER.validate_python({**row.payload, "seq": row.seq, "at": row.at,
                                         "actor": row.actor, "kind": row.kind})
    except ValidationError as exc:
        raise EventLogError(row.seq, row.kind, f"does not parse: {_problem(exc)}") from None


def to_row(event: ProtocolEvent) -> Event:
    """The stored form of an event: its envelope and its payload (JSON)."""
    payload = event.model_dump(mode="json", by_alias=True, exclude=set(ENVELOPE))
    return Event(seq=event.seq, at=event.at, actor=event.actor, kind=event.kind, payload=payload)
