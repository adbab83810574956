"""The study's vocabulary (Sect. V-C): the protocol's phases, where a θ comes from, who acts, and the
questionnaire. Every stored row is typed with these words, so they live at the bottom, with the
store; the protocol (:mod:`app.protocol`), the tablet and the report speak them.

The questionnaire is :data:`QUESTIONS`, the one list of it: the tablet asks these questions in this
order, the store accepts these answers, and the export and the report's Table IV and tests follow it.
"""

from __future__ import annotations

from enum import StrEnum

from pydantic import BaseModel, ConfigDict, Field, model_validator


class Phase(StrEnum):
    """The protocol's phases in order (Sect. V-C)."""

    INITIAL = "initial"  # random (Sobol) interactions that initialise the model
    LEARNING = "learning"  # batches that open with θ* followed by new queries
    BEST = "best"  # one interaction with the learned θ*
    QUESTIONNAIRE = "questionnaire"  # the questions of QUESTIONS
    VALIDATION = "validation"  # pairs: learned θ* vs a Sobol point, in random order, blind
    DONE = "done"


class ThetaOrigin(StrEnum):
    SOBOL = "sobol"  # a quasi-random point (initial batch, validation reference)
    LEARNED = "learned"  # a new query of the acquisition function
    BEST = "best"  # θ*, the best point observed so far (learning batches, best, validation)


class Actor(StrEnum):
    """Who did something recorded in the event log."""

    SYSTEM = "system"  # the application itself (trial ends, stages, resumes, interruptions)
    EXPERIMENTER = "experimenter"
    PARTICIPANT = "participant"  # the person, on the tablet
    SIMULATED_PARTICIPANT = "simulated_participant"  # "Simulated participant rates" / --auto
    LEARNER = "learner"


class Rater(StrEnum):
    """Who made a placement, an answer or a validation rating (its provenance)."""

    PARTICIPANT = "participant"
    SIMULATED_PARTICIPANT = "simulated_participant"
    EXPERIMENTER = "experimenter"  # entered by the experimenter on the participant's behalf

    @property
    def actor(self) -> Actor:
        return Actor(self.value)


class Hint(StrEnum):
    """A coactive hint after a handover (``[protocol] coactive``): which way the participant felt
    the robot should change. The tablet's words are the UI's; the θ each moves is the protocol's
    (:mod:`app.protocol.hints`)."""

    SOONER = "sooner"  # the robot should have come sooner
    LATER = "later"  # … later
    MORE = "more"  # … reacted more to the participant's hand
    LESS = "less"  # … reacted less


class Question(BaseModel):
    """One question of the questionnaire: the tablet shows ``text``, the report ``paper_text``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str = Field(pattern=r"^Q[0-9]+$", description="Q1, Q2, …: the column it becomes")
    text: str = Field(min_length=1, description="the question as the participant reads it")
    paper_text: str = Field(min_length=1, description="the study's wording, in the report")
    answers: tuple[str, ...] = Field(min_length=2)
    numeric: bool  # answers are 1..n on a Likert scale: stored "1"…, compared across scenarios
    above: float | None = Field(
        None, description="the hypothesis that answers lie above this value (numeric questions: "
                          "a one-sided sign test in the report)")

    @model_validator(mode="after")
    def _hypothesis_on_the_scale(self) -> Question:
        if self.above is not None and not (self.numeric and 1 <= self.above < len(self.answers)):
            raise ValueError(f"above = {self.above} of {self.id} must lie in [1, "
                             f"{len(self.answers)}) of a numeric question")
        return self

    def allowed(self) -> list[str]:
        """The stored values a answer may take: "1"… for a Likert scale, else the answers."""
        return ([str(i) for i in range(1, len(self.answers) + 1)] if self.numeric
                else list(self.answers))

    @property
    def scale(self) -> str:
        """The answers in brief: "1–5" or "Yes / No / Maybe"."""
        return f"1–{len(self.answers)}" if self.numeric else " / ".join(self.answers)


#: The questionnaire, in the order it is asked: the one list of it. Read it through
#: :func:`questions` and :func:`question`, which look it up when called.
QUESTIONS: tuple[Question, ...] = (
    # Worded for the participant; why each differs from the paper's wording (Sect. V-C) is in
    # docs/running-a-study.md, "The questionnaire". Ids, answers and meaning are the paper's.
    Question(id="Q1", text="When you placed a handover on the scale, it was easy to remember the "
                           "earlier handovers on the same scale.",
             paper_text="It was easy to remember the interactions within the batch.",
             answers=("Not at all", "2", "3", "4", "Perfectly"), numeric=True, above=3.0),
    Question(id="Q2", text="Did you feel that the robot kept getting better?",
             paper_text="Did you feel that the robot was constantly improving?",
             answers=("Yes", "No", "Maybe"), numeric=False),
    Question(id="Q3", text="Think only of the very last handover, just before these questions. "
                           "How well did the robot coordinate its movement with yours?",
             paper_text="Relative to the last set of parameters tried, how much did you perceive "
                        "that the robot was coordinating with you?",
             answers=("Not at all", "2", "3", "4", "Perfectly"), numeric=True),
)


def questions() -> tuple[Question, ...]:
    """The questionnaire (:data:`QUESTIONS`) in the order it is asked."""
    return QUESTIONS


def question(question_id: str) -> Question | None:
    """The question ``question_id`` of the questionnaire (None: there is none)."""
    return next((q for q in QUESTIONS if q.id == question_id), None)


def question_ids() -> list[str]:
    """The questionnaire's ids in order, e.g. for an error that names them."""
    return [q.id for q in QUESTIONS]
