"""The paper's protocol (Sect. V-C) as a fixed list of interaction slots, derived from StudyConfig.

    initial      batch 0       5 random (Sobol) points, placed on the scale
    learning     batches 1–4   θ* then 4 new queries each, placed on the scale (refreshed per batch)
    best         batch 1       1 interaction with the learned θ*, not rated
    questionnaire              Q1–Q3
    validation   batches 1–4   θ* vs a Sobol point in random order; the second is rated
                               better / worse / equal than the first

With the defaults: 5 + 20 + 1 + 8 = 34 interactions.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import StrEnum

import numpy as np
from pydantic import BaseModel, ConfigDict

from app.protocol.study_config import StudyConfig
from session_store.vocabulary import Phase, ThetaOrigin


class Rating(StrEnum):
    SCALE = "scale"  # placed on the refreshing relative scale
    VALIDATION = "validation"  # better / worse / equal than the previous interaction
    HINT = "hint"  # awaited only: a coactive hint after a placement ([protocol] coactive)
    NONE = "none"


class Slot(BaseModel):
    """One interaction of the protocol. ``learner_index`` is its 0-based index in the learner's
    schedule for the initial and learning phases, None after them."""

    model_config = ConfigDict(frozen=True)

    interaction: int  # 1-based over the session
    phase: Phase
    batch: int
    position: int  # 1-based within the batch
    batch_size: int
    rating: Rating
    origin: ThetaOrigin | None  # None: chosen by the learner (sobol / best / learned)
    learner_index: int | None


def validation_order(config: StudyConfig) -> list[bool]:
    """Per validation pair, whether the learned θ* comes first: random, seeded, blind."""
    rng = np.random.default_rng([config.seed, 0x5A11D])
    return [bool(first) for first in rng.integers(0, 2, config.validation_batches)]


def protocol_slots(config: StudyConfig) -> list[Slot]:
    slots: list[Slot] = []

    def add(phase: Phase, batch: int, size: int, rating: Rating,
            origins: Sequence[ThetaOrigin | None], learner: bool) -> None:
        for position, origin in enumerate(origins, start=1):
            index = len(slots)
            slots.append(Slot(interaction=index + 1, phase=phase, batch=batch, position=position,
                              batch_size=size, rating=rating, origin=origin,
                              learner_index=index if learner else None))

    add(Phase.INITIAL, 0, config.initial_trials, Rating.SCALE, [None] * config.initial_trials, True)
    for batch in range(1, config.learning_batches + 1):
        add(Phase.LEARNING, batch, config.batch_size, Rating.SCALE, [None] * config.batch_size, True)
    for batch in range(1, config.best_trials + 1):
        add(Phase.BEST, batch, 1, Rating.NONE, [ThetaOrigin.BEST], False)
    for batch, learned_first in enumerate(validation_order(config), start=1):
        pair = [ThetaOrigin.BEST, ThetaOrigin.SOBOL]
        add(Phase.VALIDATION, batch, 2, Rating.VALIDATION,
            pair if learned_first else pair[::-1], False)
    return slots
