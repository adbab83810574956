"""The study's vocabulary (Sect. V-C): the protocol's phases, where a θ comes from, who acts, and the
questionnaire. Every stored row is typed with these words, so they live at the bottom, with the
store; the protocol (:mod:`app.protocol`), the tablet and the report speak them.

The questionnaire is :data:`QUESTIONS`, the one list of it: the tablet asks these questions in this
order, the store accepts these answers, and the export and the report's Table IV and tests follow it.
"""

from __future__ import annotations

from enum import StrEnum

from pydantic import BaseModel, ConfigDict


class Phase(StrEnum):
    """The protocol's phases in order (Sect. V-C)."""

    INITIAL = "initial"  # random (Sobol) interactions that initialise the model
    LEARNING = "learning"  # batches that open with θ* followed by new queries
    BEST = "best"  # one interaction with the learned θ*
    QUESTIONNAIRE = "questionnaire"  # Q1–Q3
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


class Question(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str
    text: str
    answers: tuple[str, ...]
    numeric: bool  # answers are 1..n on a Likert scale

    def allowed(self) -> list[str]:
        """The stored values a answer may take: "1"… for a Likert scale, else the answers."""
        return ([str(i) for i in range(1, len(self.answers) + 1)] if self.numeric
                else list(self.answers))


QUESTIONS: tuple[Question, ...] = (
    # Worded for the participant; the paper's wording (Sect. V-C) and why each was changed are in
    # docs/running-a-study.md, "The questionnaire". Ids, answers and meaning are the paper's.
    Question(id="Q1", text="When you placed a handover on the scale, it was easy to remember the "
                           "earlier handovers on the same scale.",
             answers=("Not at all", "2", "3", "4", "Perfectly"), numeric=True),
    Question(id="Q2", text="Did you feel that the robot kept getting better?",
             answers=("Yes", "No", "Maybe"), numeric=False),
    Question(id="Q3", text="Think only of the very last handover, just before these questions. "
                           "How well did the robot coordinate its movement with yours?",
             answers=("Not at all", "2", "3", "4", "Perfectly"), numeric=True),
)
QUESTION_BY_ID: dict[str, Question] = {q.id: q for q in QUESTIONS}
