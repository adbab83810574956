"""Pydantic records at the boundary of ``app.learning``: the parameter box, scale placements,
comparisons, interactions, suggestions and fit reports.

Interaction ids are strings (the labels of the markers on the scale, "1", "2", … in Fig. 1).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from enum import StrEnum
from typing import Self

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from app.learning.errors import ParameterBoxError

InteractionId = str


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ParameterBox(_Frozen):
    """The box Θ the learner searches: names and closed bounds per parameter.

    The learner works in the unit cube ``[0, 1]^d`` obtained by normalising with these fixed
    bounds (never with bounds learned from the data). The session engine passes ``robot_io``'s
    ``THETA_BOUNDS`` (Table I); the simulated study of Sect. IV uses the unit cube itself.
    """

    names: tuple[str, ...] = Field(min_length=1)
    lower: tuple[float, ...]
    upper: tuple[float, ...]

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        if len(set(self.names)) != len(self.names):
            raise ParameterBoxError(f"names = {self.names!r} must be unique")
        if not len(self.lower) == len(self.upper) == len(self.names):
            raise ParameterBoxError(
                f"lower ({len(self.lower)}) and upper ({len(self.upper)}) must have one bound per "
                f"name ({len(self.names)})")
        for name, low, high in zip(self.names, self.lower, self.upper, strict=True):
            if not (math.isfinite(low) and math.isfinite(high) and low < high):
                raise ParameterBoxError(
                    f"bounds of {name} = [{low}, {high}] must be finite with lower < upper")
        return self

    @classmethod
    def from_bounds(cls, bounds: Mapping[str, tuple[float, float]]) -> ParameterBox:
        """Build from ``{name: (low, high)}``, e.g. ``robot_io.theta.THETA_BOUNDS``."""
        return cls(names=tuple(bounds), lower=tuple(b[0] for b in bounds.values()),
                   upper=tuple(b[1] for b in bounds.values()))

    @classmethod
    def unit_cube(cls, dim: int) -> ParameterBox:
        """``[0, 1]^dim`` with names ``x1 … xdim``: the space of the simulated study (Sect. IV)."""
        return cls(names=tuple(f"x{i + 1}" for i in range(dim)), lower=(0.0,) * dim,
                   upper=(1.0,) * dim)

    @property
    def dim(self) -> int:
        return len(self.names)

    def to_unit(self, theta: Mapping[str, float]) -> list[float]:
        """Normalise a point given by name to the unit cube; unknown, missing or outside: error."""
        if set(theta) != set(self.names):
            raise ParameterBoxError(
                f"theta has parameters {sorted(theta)}; the box has {list(self.names)}")
        unit = []
        for name, low, high in zip(self.names, self.lower, self.upper, strict=True):
            value = float(theta[name])
            if not (math.isfinite(value) and low <= value <= high):
                raise ParameterBoxError(
                    f"theta.{name} = {value!r} is outside the allowed range [{low}, {high}]")
            unit.append((value - low) / (high - low))
        return unit

    def from_unit(self, unit: Sequence[float]) -> dict[str, float]:
        """Map a unit-cube point back to the box (clipped to [0, 1] against optimiser round-off)."""
        if len(unit) != self.dim:
            raise ParameterBoxError(
                f"unit point has {len(unit)} coordinates; the box has {self.dim}")
        bounds = zip(self.names, self.lower, self.upper, unit, strict=True)
        return {name: low + min(max(float(u), 0.0), 1.0) * (high - low)
                for name, low, high, u in bounds}


class Placement(_Frozen):
    """One interaction placed on the relative scale of the current batch (Sect. III-C, Fig. 1).

    ``position`` runs from 0 ("Strongly Worse") to 1 ("Strongly Better"); only the order matters.
    Placing the marker *on* an earlier marker means "equal" and is stated explicitly with
    ``equal_to`` (the position is then that marker's), never inferred from equal floats.
    """

    interaction_id: InteractionId = Field(min_length=1)
    position: float | None = None
    equal_to: InteractionId | None = None

    @field_validator("position")
    @classmethod
    def _on_scale(cls, value: float | None) -> float | None:
        if value is not None and not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise ValueError(f"position = {value!r} is outside the scale [0, 1]")
        return value

    @model_validator(mode="after")
    def _one_of(self) -> Self:
        if (self.position is None) == (self.equal_to is None):
            raise ValueError(
                f"placement of {self.interaction_id!r} needs exactly one of position "
                f"(got {self.position!r}) or equal_to (got {self.equal_to!r})")
        if self.equal_to == self.interaction_id:
            raise ValueError(f"equal_to = {self.equal_to!r} cannot be the interaction itself")
        return self


class Comparison(_Frozen):
    """θ_winner ≻ θ_loser, one element of the data set 𝒟 of eq. (11), between interactions; with
    ``tie`` the two were placed "equal" (θ_winner ~ θ_loser, their order immaterial), which the
    learner uses only with ``ModelConfig.ties = "model"`` (:mod:`app.learning.ties`)."""

    winner: InteractionId
    loser: InteractionId
    tie: bool = False

    @model_validator(mode="after")
    def _distinct(self) -> Self:
        if self.winner == self.loser:
            raise ValueError(f"winner = loser = {self.winner!r}: an interaction cannot beat itself")
        return self


class Interaction(_Frozen):
    """One handover that was run: its id and the θ it actually used (by parameter name); or, with
    ``shown=False``, a point a coactive hint named (:mod:`app.learning.coactive`): in the data, but
    never run, so the schedule does not count it and θ* in the sample is never it."""

    interaction_id: InteractionId = Field(min_length=1)
    theta: dict[str, float]
    shown: bool = Field(True, description="a handover that was run (False: a hinted point)")


class TieHandling(StrEnum):
    """What the learner does with an "equal" placement (``[learner] ties``)."""

    DROP = "drop"  #: no comparison: the paper's rule (Sect. III-C)
    MODEL = "model"  #: a tie in the likelihood (:mod:`app.learning.ties`)


class Settledness(_Frozen):
    """How settled θ* is after a batch: the posterior probability that the recommended θ* is
    within ``epsilon`` of the best θ in utility (its regret is at most ε), estimated from joint
    posterior draws (:mod:`app.learning.settled`). ``regrets``: each draw's regret of θ*, sorted
    (so any ε can be asked)."""

    probability: float = Field(ge=0.0, le=1.0, description="P(regret of θ* ≤ epsilon)")
    epsilon: float = Field(gt=0.0)
    regrets: tuple[float, ...] = Field(min_length=1)
    theta: dict[str, float] = Field(description="the θ* it is about")

    def probability_within(self, epsilon: float) -> float:
        """The share of draws in which θ*'s regret is at most ``epsilon``."""
        return bisect.bisect_right(self.regrets, epsilon) / len(self.regrets)


class NextBatchGain(_Frozen):
    """What the next learning batch is expected to gain over θ* (:mod:`app.learning.gain`):
    ``gain`` = max over the box of E[(u(θ) − u(θ*))⁺] (EUBO with θ* as the previous winner),
    ``queries`` the new handovers of that batch (q − 1)."""

    gain: float = Field(ge=0.0, description="max over θ of E[(u(θ) − u(θ*))⁺], latent utility")
    queries: int = Field(ge=1, description="new handovers in the next batch (q − 1)")
    theta: dict[str, float] = Field(description="the θ* it is about")
    candidate: dict[str, float] = Field(description="the θ of the largest expected gain")

    def chance(self, epsilon: float) -> float:
        """The bound (q − 1)·g/ε, capped at 1, on the probability that the next batch shows a
        handover whose utility exceeds θ*'s by more than ``epsilon`` (Markov's inequality per
        handover, a union bound over the batch)."""
        return min(1.0, self.queries * self.gain / epsilon)


class SlotKind(StrEnum):
    """What an interaction of the schedule shows (Sect. III-C)."""

    INITIAL = "initial"  #: a Sobol point of the initial batch
    BEST = "best"  #: θ*, the best point observed so far, opening a learning batch
    QUERY = "query"  #: a new point chosen by the acquisition function
    DONE = "done"  #: the schedule is complete


class RecommendationName(StrEnum):
    """How θ*, the learned best, is recommended from the posterior of eq. (13).

    The batch-opening θ* of the schedule (Sect. III-C) is always the in-sample incumbent: it is a
    handover the participant has felt, the reference of the refreshing scale. The strategy decides
    the θ* the learner *recommends* (``PreferenceLearner.best``): the protocol's final "best"
    interaction, validation, and what a session stores as learned.
    """

    IN_SAMPLE_MEAN = "in_sample_mean"  #: the observed point with the largest posterior mean
    POSTERIOR_MEAN = "posterior_mean"  #: argmax of the posterior mean over the whole box
    IN_SAMPLE_LCB = "in_sample_lcb"  #: the observed point with the largest mean − β·std


class Slot(_Frozen):
    """Position of one interaction in the batch schedule."""

    index: int = Field(ge=0, description="0-based interaction index over the whole session")
    kind: SlotKind
    batch: int = Field(ge=0, description="0 is the initial batch")
    position: int = Field(ge=1, description="j of eq. (16): 1-based index within the batch")


class FitReport(_Frozen):
    """Outcome of one model update. A failed fit keeps the previous model (``fit_failed``)."""

    refitted: bool = Field(False, description="the model was updated (new comparisons arrived)")
    hyperparameters_fitted: bool = Field(
        False, description="the kernel hyperparameters were fitted (not only the posterior)")
    fit_failed: bool = False
    message: str | None = None
    n_points: int = 0
    n_comparisons: int = 0
    seconds: float = 0.0


class BestPoint(_Frozen):
    """θ*: the recommended point, by the strategy that produced it (``strategy``)."""

    theta: dict[str, float]
    interaction_ids: tuple[InteractionId, ...] = Field(
        description="the interactions that showed θ*; empty when θ* was not shown (posterior_mean)")
    utility_mean: float | None = Field(description="posterior mean at θ*, None without a model")
    strategy: RecommendationName | None = Field(
        None, description="the recommendation strategy; None before a model exists (θ* is then "
        "the first point shown)")


class Suggestion(_Frozen):
    """The θ to run next, with where it sits in the schedule and how it was obtained."""

    theta: dict[str, float] | None = Field(description="None when the schedule is done")
    slot: Slot
    fit: FitReport = FitReport()
    fallback: bool = Field(False, description="made by the caller-side fallback, not the learner")
    worker_restarts: int = 0


class PosteriorSlice(_Frozen):
    """The posterior utility of eq. (13) along one parameter through θ*, the others held at θ*."""

    parameter: str
    values: tuple[float, ...] = Field(description="the parameter's values, in its own units")
    mean: tuple[float, ...] = Field(description="posterior mean utility at each value")
    std: tuple[float, ...] = Field(description="posterior standard deviation at each value")
