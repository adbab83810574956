"""Choosing the next query: qNEI (the paper's choice), qLogNEI, EUBO, and Sobol as the baseline.

- ``qnei``: Monte-Carlo noisy expected improvement [Letham et al.], the noise-robust form of
  EI (14): θ = argmax E[max{0, u(θ) − max_i u(θ_i)} | 𝒟], the incumbent being integrated over the
  posterior at the observed points (``X_baseline``) instead of taken as a known u(θ*).
- ``qlognei``: the same quantity optimised on a log scale (better-behaved gradients where EI ≈ 0).
- ``eubo``: analytic expected utility of the best option [Lin et al.] for the pair (θ, θ*), i.e.
  E[max{u(θ), u(θ*)}], with θ* as ``previous_winner`` so one new point is chosen per interaction.
- ``sobol``: the next point of a scrambled Sobol sequence; uses no model (non-learning baseline).

All acquisitions choose one point at a time (q = 1 in BoTorch's sense): the paper refits and samples
after every interaction, so the batch of the scale is not a joint acquisition batch.
Everything works in the unit cube; seeds fix the MC base samples and the optimiser's starts.
"""

from __future__ import annotations

import warnings

import torch
from botorch.acquisition import AcquisitionFunction
from botorch.acquisition.logei import qLogNoisyExpectedImprovement
from botorch.acquisition.monte_carlo import qNoisyExpectedImprovement
from botorch.acquisition.preference import AnalyticExpectedUtilityOfBestOption
from botorch.exceptions.warnings import BadInitialCandidatesWarning, NumericsWarning
from botorch.models.pairwise_gp import PairwiseGP
from botorch.optim import optimize_acqf
from botorch.sampling.normal import SobolQMCNormalSampler
from linear_operator.utils.warnings import NumericalWarning
from torch.quasirandom import SobolEngine

from app.learning.config import AcquisitionName, OptimizerConfig
from app.learning.expected_warnings import expected_warnings
from app.learning.rng import seeded


def sobol_points(dim: int, seed: int, start: int, count: int) -> torch.Tensor:
    """Points ``start … start+count−1`` of the scrambled Sobol sequence with ``seed`` (float64)."""
    engine = SobolEngine(dim, scramble=True, seed=seed % 2**31)
    if start:
        engine.fast_forward(start)
    return engine.draw(count, dtype=torch.float64)


def build_acquisition(name: AcquisitionName, model: PairwiseGP, best_x: torch.Tensor,
                      config: OptimizerConfig, seed: int) -> AcquisitionFunction:
    """The BoTorch acquisition ``name`` on ``model``; ``best_x`` is θ* (unit cube, shape d)."""
    sampler = SobolQMCNormalSampler(sample_shape=torch.Size([config.mc_samples]), seed=seed)
    if name is AcquisitionName.QNEI:
        with warnings.catch_warnings():
            # qNEI warns on every construction that qLogNEI is numerically better; qNEI is the
            # paper's method and qlognei is offered separately.
            warnings.simplefilter("ignore", NumericsWarning)
            return qNoisyExpectedImprovement(model, X_baseline=model.datapoints, sampler=sampler,
                                             cache_root=False)
    if name is AcquisitionName.QLOGNEI:
        return qLogNoisyExpectedImprovement(model, X_baseline=model.datapoints, sampler=sampler,
                                            cache_root=False)
    if name is AcquisitionName.EUBO:
        return AnalyticExpectedUtilityOfBestOption(pref_model=model,
                                                   previous_winner=best_x.reshape(1, -1))
    raise ValueError(f"acquisition = {name!r} uses no model; allowed: qnei, qlognei, eubo")


def propose(name: AcquisitionName, model: PairwiseGP, best_x: torch.Tensor,
            config: OptimizerConfig, seed: int) -> torch.Tensor:
    """The unit-cube point (shape d) maximising acquisition ``name``; deterministic in ``seed``."""
    dim = best_x.shape[-1]
    bounds = torch.stack([torch.zeros(dim, dtype=torch.float64),
                          torch.ones(dim, dtype=torch.float64)])
    with seeded(seed), expected_warnings(NumericalWarning, BadInitialCandidatesWarning,
                                         context=f"acquisition {name}"):
        # NumericalWarning: jitter added to a near-singular joint posterior covariance, e.g. when a
        # candidate approaches an observed point. BadInitialCandidatesWarning: the model is sure
        # that no raw sample improves on θ* (noiseless data near convergence), so the starts of
        # L-BFGS-B are drawn at random, which is BoTorch's designed fallback.
        acqf = build_acquisition(name, model, best_x, config, seed)
        candidate, _ = optimize_acqf(acqf, bounds=bounds, q=1, num_restarts=config.num_restarts,
                                     raw_samples=config.raw_samples,
                                     options=config.scipy_options)
    return candidate.detach().reshape(dim)
