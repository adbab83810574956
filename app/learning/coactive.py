"""Coactive hints: "the robot should have …" after a handover, as comparisons.

Tucker et al.'s coactive feedback (the paper's refs. [14], [15]: preference-based gait optimisation
for exoskeletons, where the user, besides comparing, says in which direction one parameter should
change): a hint about the handover run with θ names a parameter and a sign, and becomes one
comparison θ' ≻ θ, with θ' = θ moved by ``step`` of that parameter's range along the sign, clipped
to the box. θ' is never run: it enters the data as ``Interaction(shown=False)``, a point the GP
takes like any other but that the schedule does not count and that θ* in the sample never is.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from app.learning.errors import ParameterBoxError
from app.learning.models import Comparison, Interaction, InteractionId, ParameterBox

#: Below this share of a parameter's range, θ stands at the edge the hint points past: no comparison.
EDGE = 1e-3


class HintDirection(BaseModel):
    """Which parameter a hint moves, and which way."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    parameter: str = Field(min_length=1)
    sign: Literal[-1, 1]


def hinted_theta(theta: Mapping[str, float], box: ParameterBox, direction: HintDirection,
                 step: float) -> dict[str, float] | None:
    """θ' = θ + sign·step·(range of the parameter), clipped to the box; None when θ already stands
    at that edge (θ' would be θ: the hint says nothing the learner can use)."""
    if direction.parameter not in box.names:
        raise ParameterBoxError(f"hint parameter = {direction.parameter!r} is not one of "
                                f"{list(box.names)}")
    if not 0.0 < step <= 1.0:
        raise ParameterBoxError(f"hint step = {step!r} is outside the allowed range (0, 1] "
                                "(a share of the parameter's range)")
    i = box.names.index(direction.parameter)
    low, high = box.lower[i], box.upper[i]
    value = float(theta[direction.parameter])
    moved = min(max(value + direction.sign * step * (high - low), low), high)
    if abs(moved - value) < EDGE * (high - low):
        return None
    return {**{name: float(theta[name]) for name in box.names}, direction.parameter: moved}


def hint_id(interaction_id: InteractionId) -> InteractionId:
    """The learner's id of the point a hint about ``interaction_id`` named."""
    return f"hint-{interaction_id}"


def hint_observations(interaction_id: InteractionId, hinted: Mapping[str, float] | None
                      ) -> tuple[list[Interaction], list[Comparison]]:
    """What a hint about the handover ``interaction_id`` adds to the learner: the hinted point θ'
    (:func:`hinted_theta`; not shown) and θ' ≻ θ; nothing without θ' (θ stood at the edge)."""
    if hinted is None:
        return [], []
    point = hint_id(interaction_id)
    return ([Interaction(interaction_id=point, theta=dict(hinted), shown=False)],
            [Comparison(winner=point, loser=interaction_id)])


def felt_hint(utility_gain: Mapping[HintDirection, float], noise: float, threshold: float,
              rng: np.random.Generator) -> HintDirection | None:
    """The hint a simulated participant gives: each direction's gain in utility, felt with noise
    N(0, σ²) (a first impression, eq. (16) with j = 1); the direction felt best, if it feels better
    by more than ``threshold`` (the just-noticeable difference), else no hint."""
    felt = {d: gain + rng.normal(0.0, noise) for d, gain in utility_gain.items()}
    best = max(felt, key=lambda d: felt[d], default=None)
    return best if best is not None and felt[best] > threshold else None
