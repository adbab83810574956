"""The batch schedule of Sect. III-C: which kind of θ each interaction shows.

An initial batch of ``n_initial`` quasi-random (Sobol) points, then learning batches of ``q``
interactions, each opening with θ* (the best point observed so far) followed by ``q − 1`` new
queries, until ``n_unique`` distinct points have been shown (θ* repeats are not new). The last batch
is shorter when the remaining queries do not fill one.

- Human study (Sect. V-C): ``n_initial = 5, q = 5, n_unique = 21`` → 5 + 4 batches of 5 = 25
  interactions (the final interaction with the learned best is the protocol's, not the schedule's).
- Simulated study (Sect. IV): ``n_initial = 5, n_unique = 25``; q = 2 → 5 + 20·2 = 45 interactions,
  q = 5 → 5 + 5·5 = 30.
"""

from __future__ import annotations

import math
from typing import Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.learning.models import Slot, SlotKind


class BatchSchedule(BaseModel):
    """Sizes of the schedule. Defaults are the paper's (5 initial points, q = 5, 25 unique)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    n_initial: int = Field(5, ge=1, description="Sobol points of the initial batch (paper: 5)")
    q: int = Field(5, ge=2, description="interactions per learning batch, θ* included (paper: 5)")
    n_unique: int = Field(25, ge=1, description="distinct points shown (paper, Sect. IV: 25)")

    @model_validator(mode="after")
    def _enough(self) -> Self:
        if self.n_unique < self.n_initial:
            raise ValueError(f"n_unique = {self.n_unique} must be at least n_initial = "
                             f"{self.n_initial}")
        return self

    @property
    def n_queries(self) -> int:
        """New points chosen by the acquisition function."""
        return self.n_unique - self.n_initial

    @property
    def n_batches(self) -> int:
        """Learning batches after the initial one."""
        return math.ceil(self.n_queries / (self.q - 1))

    @property
    def n_interactions(self) -> int:
        """Interactions in all: initial points, queries, and one θ* per learning batch."""
        return self.n_unique + self.n_batches

    def slot(self, index: int) -> Slot:
        """The slot of interaction ``index`` (0-based); ``DONE`` past the end."""
        if index < 0:
            raise ValueError(f"interaction index = {index} must be ≥ 0")
        if index < self.n_initial:
            return Slot(index=index, kind=SlotKind.INITIAL, batch=0, position=index + 1)
        if index >= self.n_interactions:
            return Slot(index=index, kind=SlotKind.DONE, batch=self.n_batches + 1, position=1)
        batch, offset = divmod(index - self.n_initial, self.q)
        kind = SlotKind.BEST if offset == 0 else SlotKind.QUERY
        return Slot(index=index, kind=kind, batch=batch + 1, position=offset + 1)

    def slots(self) -> list[Slot]:
        """All slots of the schedule, in order."""
        return [self.slot(i) for i in range(self.n_interactions)]


#: Sect. V-C: 5 random interactions, then 4 learning batches of 5 (θ* + 4 queries).
PAPER_SESSION_SCHEDULE = BatchSchedule(n_initial=5, q=5, n_unique=21)
