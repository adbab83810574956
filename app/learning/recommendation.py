"""Recommending θ*, the learned best, from the posterior of eq. (13).

- ``in_sample_mean``: the observed point with the largest posterior mean (the paper's θ*).
- ``posterior_mean``: the maximiser of the posterior mean over the whole box (BoTorch's
  ``PosteriorMean`` optimised with ``optimize_acqf``), kept only where its posterior mean exceeds the
  in-sample incumbent's. Under the noise of eq. (16) the mean
  surface pools the evidence of nearby points, where the in-sample argmax picks the one point
  whose placements happened to be lucky.
- ``in_sample_lcb``: the observed point with the largest mean − β·std: a point compared often is
  preferred over one that looks good on little evidence.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from botorch.acquisition import PosteriorMean
from botorch.exceptions.warnings import BadInitialCandidatesWarning
from botorch.models.pairwise_gp import PairwiseGP
from botorch.optim import optimize_acqf
from linear_operator.utils.warnings import NumericalWarning

from app.learning.config import OptimizerConfig
from app.learning.data import PreferenceData
from app.learning.expected_warnings import expected_warnings
from app.learning.models import RecommendationName
from app.learning.preference_model import posterior_at
from app.learning.rng import seeded


class Recommendation(NamedTuple):
    """A recommended θ* in the unit cube, its posterior mean, its index if it was observed."""

    unit: list[float]
    mean: float
    #: not ``index``: that would shadow ``tuple.index``
    observed_index: int | None


def recommend(strategy: RecommendationName, model: PairwiseGP, data: PreferenceData,
              optimizer: OptimizerConfig, seed: int, lcb_beta: float = 1.0) -> Recommendation:
    """θ* by ``strategy`` (unit cube); deterministic in ``seed``. ``data`` must be non-empty."""
    X, _ = data.tensors()
    mean, std = posterior_at(model, X)
    unshown = data.unshown_penalty()  # in the sample: a handover the participant felt
    if strategy is RecommendationName.IN_SAMPLE_LCB:
        index = int((mean - lcb_beta * std + unshown).argmax())
        return Recommendation(data.points[index], float(mean[index]), index)
    index = int((mean + unshown).argmax())
    incumbent = Recommendation(data.points[index], float(mean[index]), index)
    if strategy is RecommendationName.IN_SAMPLE_MEAN:
        return incumbent
    dim = X.shape[-1]
    bounds = torch.stack([torch.zeros(dim, dtype=torch.float64),
                          torch.ones(dim, dtype=torch.float64)])
    with seeded(seed), expected_warnings(NumericalWarning, BadInitialCandidatesWarning,
                                         context="posterior-mean recommendation"):
        candidate, value = optimize_acqf(PosteriorMean(model), bounds=bounds, q=1,
                                         num_restarts=optimizer.num_restarts,
                                         raw_samples=optimizer.raw_samples,
                                         options=optimizer.scipy_options)
    if float(value) <= incumbent.mean:
        return incumbent
    return Recommendation(candidate.detach().reshape(dim).tolist(), float(value), None)
