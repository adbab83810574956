"""What the next learning batch is expected to gain over θ* (issue 46): the signal of a stopping
rule that weighs what one more batch may find against what it costs the participant.

The gain of a handover θ over θ* is the expected utility of the better of the two minus θ*'s,

    g(θ) = E[max(u(θ), u(θ*))] − E[u(θ*)] = E[(u(θ) − u(θ*))⁺],

under the posterior of eq. (13): the expected utility of the best option (EUBO, Lin et al.,
"Preference exploration for efficient Bayesian optimization with multiple outcomes", AISTATS
2022) with θ* as the previous winner, which is exactly BoTorch's
``AnalyticExpectedUtilityOfBestOption(previous_winner=θ*)``. Its maximum over the box,
g = max_θ g(θ), is what the most promising next handover is expected to add to θ*: the pairwise
analogue of the expected improvement whose comparison with a cost stops cost-aware Bayesian
optimisation (Xie et al., arXiv 2507.12453).

The cost is said in the participant's terms. A handover θ is preferred to θ* more than a share p of
the time when u(θ) − u(θ*) > ε_p = √2·Φ⁻¹(p) (the probit of eq. (13); app.learning.settled's ε),
and by Markov's inequality P(u(θ) − u(θ*) > ε_p) ≤ g(θ)/ε_p ≤ g/ε_p for every θ. Over the q − 1
new handovers of the next batch (a union bound),

    P(the next batch shows a handover preferred to θ* more than p of the time) ≤ (q − 1)·g/ε_p,

the ``chance`` of :class:`~app.learning.models.NextBatchGain`. A rule that stops once this bound is
at most α stops when "the next batch is unlikely (less than α) to find a handover preferred to θ*
more than p of the time": the cost of a batch is λ = α·ε_p/(q − 1) in latent utility.
"""

from __future__ import annotations

import torch
from botorch.acquisition.preference import AnalyticExpectedUtilityOfBestOption
from botorch.exceptions.warnings import BadInitialCandidatesWarning
from botorch.models.pairwise_gp import PairwiseGP
from botorch.optim import optimize_acqf
from linear_operator.utils.warnings import NumericalWarning

from app.learning.config import OptimizerConfig
from app.learning.expected_warnings import expected_warnings
from app.learning.rng import seeded


def best_gain(model: PairwiseGP, theta_star: list[float], optimizer: OptimizerConfig,
              seed: int) -> tuple[float, list[float]]:
    """g = max over the unit cube of E[(u(θ) − u(θ*))⁺] (BoTorch's analytic EUBO with θ* as the
    previous winner, which returns exactly this gain) and the θ (unit cube) that attains it;
    deterministic in ``seed``."""
    dim = len(theta_star)
    bounds = torch.stack([torch.zeros(dim, dtype=torch.float64),
                          torch.ones(dim, dtype=torch.float64)])
    winner = torch.tensor([theta_star], dtype=torch.float64)
    with seeded(seed), expected_warnings(NumericalWarning, BadInitialCandidatesWarning,
                                         context="expected gain of the next batch"):
        acqf = AnalyticExpectedUtilityOfBestOption(pref_model=model, previous_winner=winner)
        candidate, value = optimize_acqf(acqf, bounds=bounds, q=1,
                                         num_restarts=optimizer.num_restarts,
                                         raw_samples=optimizer.raw_samples,
                                         options=optimizer.scipy_options)
    return max(float(value), 0.0), candidate.detach().reshape(dim).tolist()
