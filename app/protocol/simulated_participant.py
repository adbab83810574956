"""A simulated participant who rates handovers from a latent utility (for --auto sessions and tests).

Taste: the participant likes the robot to arrive together with their hand, with a personal preferred
arrival gap g* (robot − hand, seconds): u(trial) = −|gap − g*|. Like Sect. IV's simulated user, their
impression of the j-th interaction of a batch is noisy, more so later in the batch:
y = u + j·N(0, σ²) (eq. 16). Every draw is seeded by (participant seed, interaction), so a resumed
session rates exactly like one that never stopped.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, Field

from app.protocol.state import Marker
from session_store.models import Trial
from session_store.vocabulary import Hint, question, question_ids


class Taste(BaseModel):
    preferred_gap_s: float = Field(description="g*: robot arrival − hand arrival liked best [s]")
    noise_s: float = Field(gt=0, description="σ of eq. (16), in seconds of arrival gap")
    tie_s: float = Field(gt=0, description="impressions closer than this feel 'equal'")
    hint_s: float = Field(0.1, gt=0, description="a coactive hint when the felt arrival gap misses "
                                                 "g* by more than this [s]")


class SimulatedParticipant:
    def __init__(self, seed: int, taste: Taste | None = None) -> None:
        self.seed = seed
        rng = np.random.default_rng([seed, 0x7A57])
        self.taste = taste or Taste(preferred_gap_s=float(rng.uniform(-0.1, 0.25)),
                                    noise_s=float(rng.uniform(0.02, 0.06)), tie_s=0.03)

    def utility(self, trial: Trial) -> float:
        """u = −|gap − g*|; a handover in which robot or hand never arrived is the worst."""
        if trial.arrival_gap_s is None:
            return -10.0
        return -abs(trial.arrival_gap_s - self.taste.preferred_gap_s)

    def impression(self, trial: Trial, position: int) -> float:
        """y = u + j·N(0, σ²) (eq. 16), the same draw whenever this interaction is recalled."""
        noise = np.random.default_rng([self.seed, trial.interaction, 0x1A9]).normal()
        return self.utility(trial) + position * self.taste.noise_s * noise

    def place(self, trial: Trial, position: int, earlier: list[tuple[Marker, Trial]]
              ) -> tuple[float | None, int | None]:
        """Where to put the newest interaction: ``(position, None)`` or ``(None, equal_to)``.

        Between the markers it feels worse than and those it feels better than; on a marker whose
        impression is within ``tie_s`` ("equal").
        """
        y = self.impression(trial, position)
        felt = [(m, self.impression(t, m.label)) for m, t in earlier]
        ties = [(abs(v - y), m) for m, v in felt if abs(v - y) < self.taste.tie_s]
        if ties:
            return None, min(ties, key=lambda pair: pair[0])[1].interaction
        lower = max((m.position for m, v in felt if v < y), default=0.0)
        upper = min((m.position for m, v in felt if v > y), default=1.0)
        return (lower + upper) / 2.0, None

    def hint(self, trial: Trial, position: int) -> Hint | None:
        """A coactive hint about the handover just placed (``[protocol] coactive``): "sooner" when
        the robot felt later than g* by more than ``hint_s``, "later" when it felt earlier, else
        none. The felt gap is the impression's (eq. 16: j·N(0, σ²)), with a draw of its own."""
        if trial.arrival_gap_s is None:
            return None
        noise = np.random.default_rng([self.seed, trial.interaction, 0x417]).normal()
        miss = trial.arrival_gap_s + position * self.taste.noise_s * noise - self.taste.preferred_gap_s
        if abs(miss) <= self.taste.hint_s:
            return None
        return Hint.SOONER if miss > 0 else Hint.LATER

    def rate(self, first: Trial, second: Trial) -> str:
        """The second of a validation pair against the first: better, worse or equal."""
        difference = self.impression(second, 2) - self.impression(first, 1)
        if abs(difference) < self.taste.tie_s:
            return "equal"
        return "better" if difference > 0 else "worse"

    def answer(self, question_id: str, best: Trial | None) -> str:
        """Q3 (coordination of the last θ, 1–5) from how good ``best`` was; any other question at
        random: a word (Q2: Yes/No/Maybe) or 3–5 on a scale (Q1, memory)."""
        asked = question(question_id)
        if asked is None:
            raise ValueError(f"question_id = {question_id!r} is not one of {question_ids()}")
        rng = np.random.default_rng([self.seed, 0xA25, ord(question_id[-1])])
        if not asked.numeric:
            return str(rng.choice(asked.answers))
        top = len(asked.answers)
        if question_id == "Q3" and best is not None:
            miss = -self.utility(best)
            score = 5 if miss < 0.1 else 4 if miss < 0.25 else 3 if miss < 0.5 else 2
            return str(int(np.clip(score + rng.integers(-1, 1, endpoint=True), 1, top)))
        return str(int(rng.integers(min(3, top), top, endpoint=True)))
