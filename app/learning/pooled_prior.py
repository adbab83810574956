"""Pool earlier participants' learners into a :class:`~app.learning.prior.PopulationPrior`, the
prior mean of eq. (12) for a new participant (evaluated by :mod:`app.learning.population`).

For a study folder, the session side collects the :class:`~app.learning.config.LearnerSnapshot` of
each completed participant of the same scenario (the last ``state`` stored) and calls::

    prior = population_prior({"P01": snapshot_1, "P02": snapshot_2, ...}, weight=1.0)
    config = LearnerConfig(box=..., prior=prior, ...)   # recorded in every snapshot: prior.sources

The earlier participants' models are rebuilt from their stored hyperparameters (zero prior mean, so
priors never chain) and their posterior means pooled, see :mod:`app.learning.prior`.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from botorch.models.pairwise_gp import PairwiseGP

from app.learning.config import LearnerSnapshot
from app.learning.errors import LearningError
from app.learning.learner import PreferenceLearner
from app.learning.prior import PopulationPrior, PriorComponent


def component_of(source: str, model: PairwiseGP) -> PriorComponent:
    """One participant's posterior mean k(x, X)·α as data (its model has a zero prior mean)."""
    X = model.datapoints
    alpha = torch.cholesky_solve(model.utility.detach().unsqueeze(-1), model.covar_chol.detach())
    kernel = model.covar_module
    return PriorComponent(
        source=source, points=X.tolist(), coefficients=alpha.reshape(-1).tolist(),
        lengthscale=kernel.base_kernel.lengthscale.detach().reshape(-1).tolist(),
        outputscale=float(kernel.outputscale.detach()))


def population_prior(snapshots: Mapping[str, LearnerSnapshot],
                     weight: float = 1.0) -> PopulationPrior:
    """The prior mean for a new participant from earlier participants' learner snapshots.

    ``snapshots`` maps a participant id to its final snapshot; participants without a model (no
    comparison) contribute nothing. Raises :class:`LearningError` when none has a model or the
    boxes differ (priors only transfer within one parameter box, i.e. one scenario's study).
    """
    boxes = {s.config.box for s in snapshots.values()}
    if len(boxes) > 1:
        raise LearningError(f"snapshots = {sorted(snapshots)} come from {len(boxes)} different "
                            "parameter boxes; a prior needs participants of one box")
    components = []
    for source, snapshot in snapshots.items():
        zero_mean = snapshot.model_copy(update={"config": snapshot.config.model_copy(
            update={"prior": None})})
        model = PreferenceLearner.restore(zero_mean).model.model
        if model is not None:
            components.append(component_of(source, model))
    if not components:
        raise LearningError(f"snapshots = {sorted(snapshots)}: none has a fitted preference "
                            "model (no comparisons), so there is no prior to pool")
    return PopulationPrior(weight=weight, components=components)
