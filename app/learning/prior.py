"""Priors from earlier participants as plain data (torch-free, so configs can carry them).

The zero mean of eq. (12) says nothing about where good handovers lie. After a few participants of
the same scenario the lab knows more: :func:`app.learning.pooled_prior.population_prior` turns their
learner data into a :class:`PopulationPrior`, the pooled posterior mean of eq. (13) of the earlier
participants, which becomes the GP's prior mean m(θ) for the next one,

    u ~ GP(w · m̄(θ), k(θ, θ')),   m̄(θ) = (1/P) Σ_p k_p(θ, X_p) α_p,

each earlier participant p contributing its posterior mean k_p(θ, X_p) α_p (RBF kernel with its own
fitted hyperparameters, α_p = K_p⁻¹ f̂_p for its MAP utilities f̂_p). ``weight`` w scales it. The new
participant's comparisons override it where they have data: the posterior mean there follows the
likelihood, and the prior only fills in where the participant has not been.
"""

from __future__ import annotations

from typing import Self

from pydantic import BaseModel, ConfigDict, Field, model_validator


class PriorComponent(BaseModel):
    """One earlier participant's posterior mean of u, in the unit cube of the learner's box."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    source: str = Field(min_length=1, description="who it came from, e.g. the participant id")
    points: list[list[float]] = Field(min_length=1, description="X_p, unit-cube points")
    coefficients: list[float] = Field(min_length=1, description="α_p = K_p⁻¹ f̂_p")
    lengthscale: list[float] = Field(min_length=1, description="RBF lengthscale per dimension")
    outputscale: float = Field(gt=0.0)

    @model_validator(mode="after")
    def _shapes(self) -> Self:
        if len(self.coefficients) != len(self.points):
            raise ValueError(f"coefficients has {len(self.coefficients)} entries for "
                             f"{len(self.points)} points; one per point is required")
        dims = {len(p) for p in self.points}
        if dims != {len(self.lengthscale)}:
            raise ValueError(f"points have dimension {sorted(dims)}, lengthscale has "
                             f"{len(self.lengthscale)} entries; they must agree")
        return self


class PopulationPrior(BaseModel):
    """The prior mean w · m̄(θ) from earlier participants; recorded with every learner config."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    weight: float = Field(1.0, ge=0.0, le=10.0, description="w, the weight of the pooled mean")
    components: list[PriorComponent] = Field(min_length=1)

    @property
    def sources(self) -> list[str]:
        """The participants that fed the prior, in order."""
        return [c.source for c in self.components]
