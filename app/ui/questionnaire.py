"""The questionnaire as the participant goes through it: one question per screen, Back and Next.

The engine stores each answer once (a stored answer cannot be changed), so the tablet keeps the
participant's choices on the page — like the scale's handle before Confirm — and stores them all
with the last Next. Until then Back and Next move freely between the questions and a choice can be
changed. A reload or a lost connection before the last Next forgets the choices (nothing was
stored); a questionnaire that was stored in part (the server stopped during the last Next)
continues with the questions still unanswered. Pure: no GUI, no engine.
"""

from __future__ import annotations

from pydantic import BaseModel, Field, model_validator

from session_store.vocabulary import question, question_ids


class Draft(BaseModel):
    """The participant's choices for the ``questions`` still unanswered, and the page shown."""

    questions: tuple[str, ...] = Field(min_length=1)
    page: int = 0
    chosen: dict[str, str] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _known(self) -> Draft:
        unknown = [q for q in self.questions if question(q) is None]
        if unknown:
            raise ValueError(f"questions = {unknown} are not among {question_ids()}")
        if not 0 <= self.page < len(self.questions):
            raise ValueError(f"page = {self.page} must lie in [0, {len(self.questions) - 1}]")
        return self

    @property
    def question(self) -> str:
        return self.questions[self.page]

    @property
    def number(self) -> int:
        """The question's 1-based number in the whole questionnaire ("2 of 3")."""
        return question_ids().index(self.question) + 1

    @property
    def first(self) -> bool:
        return self.page == 0

    @property
    def last(self) -> bool:
        return self.page == len(self.questions) - 1

    @property
    def choice(self) -> str | None:
        return self.chosen.get(self.question)

    def choose(self, value: str) -> Draft:
        return self.model_copy(update={"chosen": {**self.chosen, self.question: value}})

    def back(self) -> Draft:
        return self if self.first else self.model_copy(update={"page": self.page - 1})

    def next(self) -> Draft:
        """The next page (only once this one has a choice)."""
        if self.choice is None or self.last:
            return self
        return self.model_copy(update={"page": self.page + 1})

    def complete(self) -> list[tuple[str, str]]:
        """(question, value) in order, once every question has a choice; else []."""
        if any(q not in self.chosen for q in self.questions):
            return []
        return [(q, self.chosen[q]) for q in self.questions]
