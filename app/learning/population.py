"""Priors from earlier participants as the GP prior mean of eq. (12) for a new participant: a
:class:`~app.learning.prior.PopulationPrior` (built by :mod:`app.learning.pooled_prior`) evaluated,
and the PairwiseGP that adds it to its prior mean.
"""

from __future__ import annotations

import torch
from botorch.models.pairwise_gp import PairwiseGP
from gpytorch.means import Mean

from app.learning.prior import PopulationPrior

#: Unit-cube distance beyond which two earlier participants' favourites count as different
#: handovers for the initial batch (:meth:`PopulationMean.initial_design`): at the paper's noise a
#: batch's last placement is off by up to 5·σ = 0.15–0.25 in u, and u differs by at most the
#: distance between the two points.
DISTINCT_FAVOURITES = 0.25


class PopulationMean(Mean):
    """w · m̄(x): the pooled posterior mean of earlier participants, a fixed (not fitted) mean.

    All components are stacked into one set of points with per-point lengthscales and weights
    (s_p·α_p·w/P), so an evaluation is one kernel matrix, whatever the number of participants.
    """

    def __init__(self, prior: PopulationPrior) -> None:
        super().__init__()
        share = prior.weight / len(prior.components)
        points: list[list[float]] = []
        lengthscales: list[list[float]] = []
        coefficients: list[float] = []
        owners: list[int] = []
        for p, c in enumerate(prior.components):
            points.extend(c.points)
            lengthscales.extend([c.lengthscale] * len(c.points))
            coefficients.extend(share * c.outputscale * a for a in c.coefficients)
            owners.extend([p] * len(c.points))
        self.register_buffer("points", torch.tensor(points, dtype=torch.float64))
        self.register_buffer("lengthscales", torch.tensor(lengthscales, dtype=torch.float64))
        self.register_buffer("coefficients", torch.tensor(coefficients, dtype=torch.float64))
        self.register_buffer("owners", torch.tensor(owners))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self._kernel(x) @ self.coefficients

    def _kernel(self, x: torch.Tensor) -> torch.Tensor:
        """exp(−½‖(x − X_p)/ℓ_p‖²) against every stacked point, ... × n × N."""
        diff = (x.unsqueeze(-2) - self.points) / self.lengthscales  # ... × n × N × d
        return torch.exp(-0.5 * diff.pow(2).sum(-1))

    def best_point(self) -> torch.Tensor:
        """The earlier participants' point (unit cube) where w · m̄ is largest: the population's
        best handover as far as it was felt, shown first to a new participant."""
        return self.points[int(torch.argmax(self.forward(self.points)))]

    def own_best_points(self) -> torch.Tensor:
        """Each earlier participant's own best: of the points p was shown, the one where p's
        posterior mean k_p(x, X_p) α_p is largest (one row per component, in order)."""
        same = self.owners.unsqueeze(-1) == self.owners
        own_mean = (self._kernel(self.points) * same) @ self.coefficients
        best = [int(torch.where(self.owners == p, own_mean, -torch.inf).argmax())
                for p in range(int(self.owners.max()) + 1)]
        return self.points[best]

    def initial_design(self, n: int) -> torch.Tensor:
        """Up to ``n`` handovers to show a new participant first: the population's best
        (:meth:`best_point`), then, one at a time, the earlier participant's own best farthest
        from those already chosen, as long as it is more than ``DISTINCT_FAVOURITES`` away from
        each of them. Where earlier participants liked different handovers (the paper's Tables
        II–III) the batch shows their favourites; where they agree it is the pooled best alone
        and the rest of the batch is left to the Sobol sequence (favourites closer than that make
        comparisons the noise of eq. (16) decides)."""
        chosen = [self.best_point()]
        candidates = self.own_best_points()
        while len(chosen) < n:
            gap = torch.cdist(candidates, torch.stack(chosen)).min(-1).values
            if float(gap.max()) <= DISTINCT_FAVOURITES:
                break
            chosen.append(candidates[int(torch.argmax(gap))])
        return torch.stack(chosen)


class PopulationPairwiseGP(PairwiseGP):
    """``PairwiseGP`` whose prior mean (eq. (12)) is a :class:`PopulationMean` instead of zero.

    BoTorch's PairwiseGP takes its prior mean from ``_prior_mean`` in the Laplace step and in the
    posterior; the population mean is added there, so fit, posterior and acquisitions all use it.
    """

    def __init__(self, datapoints: torch.Tensor, comparisons: torch.Tensor,
                 population_mean: PopulationMean, **kwargs: object) -> None:
        super().__init__(None, None, **kwargs)
        self.population_mean = population_mean
        self.set_train_data(datapoints, comparisons, update_model=True)

    def _prior_mean(self, X: torch.Tensor) -> torch.Tensor:
        return super()._prior_mean(X) + self.population_mean(X)
