"""Pydantic models of everything a study session stores: one per table of the participant database.

Times in stored rows are UTC ISO-8601 strings; positions in metres; θ as its three components.
The data dictionary of the export is ``docs/data.md``.
"""

from __future__ import annotations

from datetime import UTC, datetime
from enum import StrEnum
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from robot_io.theta import Theta
from session_store.paths import check_participant_code
from session_store.vocabulary import Actor, Hint, Phase, Rater, ThetaOrigin, question, question_ids


def utc_now() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


#: What the provenance column of placements, validation ratings and answers means.
RATER_DESCRIPTION = ("who made it: participant (on the tablet), simulated_participant (the "
                     "simulation), experimenter (on the participant's behalf); empty in rows "
                     "stored before schema version 3, whose origin was not recorded")


class _Row(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Participant(_Row):
    """The participant row: the code, when the session was created and its plan, as the protocol
    wrote it (JSON; ``app.protocol.study_config.StudyConfig`` reads it)."""

    code: str
    created_at: str = Field(default_factory=utc_now)
    config: dict[str, Any]

    @field_validator("code")
    @classmethod
    def _safe(cls, code: str) -> str:
        return check_participant_code(code)


# -- what happens ---------------------------------------------------------------------------------
class TrialOutcome(StrEnum):
    COMPLETED = "completed"  # the participant took the object (released on their pull)
    NOT_TAKEN = "not_taken"  # held out at H, but nobody pulled within the release timeout
    ABORTED = "aborted"


class SafetyRecord(_Row):
    """A trial's safety figures from its sample rows (app/protocol/safety_record.py; empty where the
    trial gives none: the hand never came near, no release), with the parameters they were taken with."""

    min_distance_m: float | None = Field(None, description="safety: closest distance of the tool "
                                         "(measured TCP) to the tracked hand [m]")
    speed_near_mps: float | None = Field(None, description="safety: largest tool speed while the "
                                         "hand was within near_radius_m [m/s]; empty: never that near")
    closing_speed_mps: float | None = Field(None, description="safety: largest closing speed of "
                                            "tool and hand (−d distance/dt) while the hand was "
                                            "within near_radius_m [m/s]")
    pull_to_open_s: float | None = Field(None, description="safety: from the start of the pull "
                                         "(≥ contact_pull_n) to the gripper open [s]; empty: no "
                                         "release")
    longest_contact_s: float | None = Field(None, description="safety: longest stretch of the hold "
                                            "with the pull ≥ contact_pull_n (the person holding "
                                            "the object in the robot's grip) [s]")
    near_radius_m: float | None = Field(None, description="safety: [safety_record] near_radius_m "
                                        "the speeds were taken within [m]")
    contact_pull_n: float | None = Field(None, description="safety: [safety_record] contact_pull_n, "
                                         "the pull that counted as contact [N]")


def _safety(name: str) -> Any:
    """A trial column of the safety record: the record's own field (empty in trials stored before
    schema version 6 and in trials that ended without samples)."""
    return Field(None, description=SafetyRecord.model_fields[name].description)


class Trial(_Row):
    """One attempt at one interaction of the protocol. An aborted attempt is repeated, never rated;
    ``interaction`` (1-based over the session) is unique among completed trials."""

    trial_index: int = Field(ge=1, description="1-based over all attempts of the session")
    interaction: int = Field(ge=1, description="the protocol's interaction this attempt is for "
                                               "(1–34 with the paper's counts)")
    attempt: int = Field(ge=1, description="1 for the first attempt, 2… after aborted ones")
    phase: Phase = Field(description="initial, learning, best or validation")
    batch: int = Field(ge=0, description="batch within the phase: 0 for the initial batch, "
                                         "1… for learning, best and validation")
    position: int = Field(ge=1, description="1-based position within the batch (j of eq. 16)")
    theta_a: float = Field(description="θ: steepness a of σ_j, eq. (10) (a_d in Tables II–III)")
    theta_delta: float = Field(description="θ: offset δ of σ_j, eq. (10) (δ_d in Tables II–III)")
    theta_k: float = Field(description="θ: coupling gain k = k_t = k_s, eqs. (8)–(9)")
    origin: ThetaOrigin = Field(description="sobol (random), learned (new query) or best (θ*)")
    hand_seed: int = Field(description="seed of the simulated hand (same for every attempt)")
    started_at: str = Field(description="UTC ISO-8601 time of Start")
    ended_at: str | None = Field(None, description="UTC ISO-8601 time the trial ended")
    outcome: TrialOutcome | None = Field(None, description="completed, not_taken or aborted (both "
                                                           "repeated, never rated); empty while "
                                                           "running")
    reason: str | None = Field(None, description="why it was aborted or not taken")
    robot_arrival_s: float | None = Field(None, description="robot at the handover point, "
                                                            "seconds after Go")
    hand_arrival_s: float | None = Field(None, description="hand at the handover point, "
                                                           "seconds after Go")
    arrival_gap_s: float | None = Field(None, description="robot − hand arrival [s]; > 0: robot "
                                                          "late")
    peak_speed_mps: float | None = Field(None, description="peak TCP speed [m/s]")
    max_tau: float | None = Field(None, description="largest τ = τ0(1 + C_t) of the trial [s]")
    deadline_misses: int | None = Field(None, description="control cycles that missed their "
                                                          "deadline (real time only)")
    go_at: str | None = Field(None, description="UTC ISO-8601 time of Go (the tablet's cue and the "
                                                "robot's start); the *_s times count from it")
    hold_s: float | None = Field(None, description="robot at H and still: hold begins, release "
                                                   "armed, seconds after Go")
    release_s: float | None = Field(None, description="the pull passed the threshold and the "
                                                      "gripper opened, seconds after Go")
    retract_end_s: float | None = Field(None, description="robot back at R, seconds after Go")
    peak_pull_n: float | None = Field(None, description="largest baseline-subtracted, filtered "
                                                        "pull while holding [N]")
    min_distance_m: float | None = _safety("min_distance_m")
    speed_near_mps: float | None = _safety("speed_near_mps")
    closing_speed_mps: float | None = _safety("closing_speed_mps")
    pull_to_open_s: float | None = _safety("pull_to_open_s")
    longest_contact_s: float | None = _safety("longest_contact_s")
    near_radius_m: float | None = _safety("near_radius_m")
    contact_pull_n: float | None = _safety("contact_pull_n")

    @property
    def theta(self) -> Theta:
        return Theta(a=self.theta_a, delta=self.theta_delta, k=self.theta_k)


class Placement(_Row):
    """Where the participant put an interaction on the refreshing relative scale (Sect. III-C).

    ``position`` runs from 0 ("Strongly Worse") to 1 ("Strongly Better"); dropping the marker on an
    earlier one of the batch means "equal" and sets ``equal_to`` (and that marker's position).
    """

    trial_index: int = Field(description="the completed trial that was placed")
    interaction: int = Field(description="its interaction")
    batch: int = Field(description="its batch (the scale is cleared after every batch)")
    position: float = Field(ge=0.0, le=1.0, description="0 = Strongly Worse … 1 = Strongly "
                                                        "Better; only the order carries meaning")
    equal_to: int | None = Field(None, description="interaction it was dropped on (= equal)")
    placed_at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time of Confirm")
    actor: Rater | None = Field(description=RATER_DESCRIPTION)


class Comparison(_Row):
    """θ of ``winner`` ≻ θ of ``loser`` (eq. 11), from the placement of interaction ``source``."""

    batch: int = Field(description="batch of both interactions")
    source: int = Field(description="interaction whose placement made this comparison")
    winner: int = Field(description="interaction preferred (θ^r of eq. 11)")
    loser: int = Field(description="interaction not preferred (θ^c of eq. 11)")

    @model_validator(mode="after")
    def _distinct(self) -> Comparison:
        if self.winner == self.loser:
            raise ValueError(f"winner = loser = {self.winner}: an interaction cannot beat itself")
        return self


class HintRow(_Row):
    """A coactive hint (``[protocol] coactive``): after placing a handover, the participant said
    which way the robot should change, or that nothing should. A hint is the comparison θ' ≻ θ of
    the handover, θ' its θ moved along the hint (Tucker et al.'s coactive feedback)."""

    trial_index: int = Field(description="the completed trial the hint is about")
    interaction: int = Field(description="its interaction")
    batch: int = Field(description="its batch")
    hint: Hint | None = Field(description="sooner, later, more (react more to the hand), less; "
                                          "empty: \"nothing to change\"")
    step: float = Field(description="how far a hint moves θ: a share of the parameter's range "
                                    "([protocol] hint_step)")
    hinted_a: float | None = Field(description="θ' (preferred to the handover's θ): a; empty "
                                               "without a hint or when θ stood at the edge")
    hinted_delta: float | None = Field(description="θ': δ")
    hinted_k: float | None = Field(description="θ': k")
    given_at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time")
    actor: Rater = Field(description=RATER_DESCRIPTION.split("; empty")[0])

    @property
    def hinted(self) -> dict[str, float] | None:
        """θ' as ``{a, delta, k}``; None without a hint or when θ stood at the edge."""
        if self.hinted_a is None or self.hinted_delta is None or self.hinted_k is None:
            return None
        return {"a": self.hinted_a, "delta": self.hinted_delta, "k": self.hinted_k}


class ValidationRating(_Row):
    """The second interaction of a validation pair rated against the first (Sect. V-C)."""

    batch: int = Field(description="validation pair 1…")
    trial_index: int = Field(description="trial of the second interaction of the pair")
    interaction: int = Field(description="the second interaction of the pair")
    rating: Literal["better", "worse", "equal"] = Field(
        description="the second interaction against the first")
    learned_preferred: bool | None = Field(
        description="the learned θ* was preferred; None when rated equal")
    rated_at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time")
    actor: Rater | None = Field(description=RATER_DESCRIPTION)


# -- questionnaire ----------------------------------------------------------------------------------
class Answer(_Row):
    """An answer to a question of the questionnaire (:data:`~session_store.vocabulary.QUESTIONS`;
    the paper's: 1–5 for Q1 and Q3, "Yes"/"No"/"Maybe" for Q2)."""

    question: str = Field(description="Q1, Q2, Q3 … (Sect. V-C; session_store.vocabulary)")
    value: str = Field(description="1–5 for a numeric question (Q1, Q3: Not at all … "
                                   "Perfectly), else one of its answers (Q2: Yes/No/Maybe)")
    answered_at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time")
    actor: Rater | None = Field(description=RATER_DESCRIPTION)

    @model_validator(mode="after")
    def _allowed(self) -> Answer:
        asked = question(self.question)
        if asked is None:
            raise ValueError(f"question = {self.question!r} is not one of {question_ids()}")
        allowed = asked.allowed()
        if self.value not in allowed:
            raise ValueError(f"answer to {self.question} = {self.value!r} is not one of {allowed}")
        return self


# -- learner and events ---------------------------------------------------------------------------
class LearnerSnapshotRow(_Row):
    """The learner after an update: θ*, its fit, and the state needed to resume it exactly."""

    after_interaction: int = Field(description="interactions observed when the next θ was planned")
    theta_star_a: float | None = Field(description="θ*: a (posterior-mean argmax over observed)")
    theta_star_delta: float | None = Field(description="θ*: δ")
    theta_star_k: float | None = Field(description="θ*: k")
    utility_mean: float | None = Field(description="posterior mean utility at θ*")
    fit_failed: bool = Field(description="the last fit failed and the previous model was kept")
    message: str | None = Field(description="the fit's error, if any")
    n_points: int = Field(description="distinct θ observed")
    n_comparisons: int = Field(description="comparisons in the data")
    state: str = Field(description="the learner's own JSON snapshot (hyperparameters, warm start)")
    created_at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time")


class Event(_Row):
    """One line of the append-only log: who did what, when. Replaying the log rebuilds the state."""

    seq: int | None = Field(None, description="position in the log, 1…")
    at: str = Field(default_factory=utc_now, description="UTC ISO-8601 time")
    actor: Actor = Field(description="system, experimenter, participant, simulated_participant "
                                     "or learner")
    kind: Annotated[str, Field(min_length=1, description="what happened (the protocol's event "
                                                         "kinds: see docs/data.md)")]
    payload: dict[str, Any] = Field(default_factory=dict, description="details, as JSON")
