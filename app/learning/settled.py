"""The stopping signal: how settled θ* is after a batch (issue 40, ``[protocol] stop_when_settled``).

The signal is the posterior probability that the recommended θ* is within ε of the best θ *in
utility* (its regret is at most ε),

    P(max_θ u(θ) − u(θ*) ≤ ε | 𝒟),

under the posterior of eq. (13). It is estimated by Monte Carlo: ``samples`` joint draws of the
utility from the posterior at a fixed set of candidates (the observed points, θ* itself and
``candidates`` scrambled Sobol points of the box); each draw's regret is its maximum minus its value
at θ*.

Why regret, not the distance in θ: a participant's best θ need not be one point. A person who cares
about when the robot arrives is indifferent along every θ with the same arrival (the simulated
participant of ``run-session --auto`` is such a person), so the posterior's argmax wanders along
that ridge however much is learned, and "θ* within ε of the best θ" never becomes sure; the
regret does. Why not "the next batch would move θ* by less than ε": it would have to simulate the
batch's placements. The regret has a meaning in the participant's own terms, because the probit of
eq. (13) fixes the noise: the best θ would be preferred to θ* with probability Φ(regret/√2). So
ε is set as that probability (app.learning.config.epsilon_for): with 0.6, "θ* is settled when the
best handover would be preferred to it at most 60 % of the time". Deterministic given ``seed``.
"""

from __future__ import annotations

import torch
from botorch.models.pairwise_gp import PairwiseGP
from linear_operator.utils.warnings import NumericalWarning

from app.learning.acquisition import sobol_points
from app.learning.data import PreferenceData
from app.learning.expected_warnings import expected_warnings
from app.learning.rng import seeded

#: Joint posterior draws and Sobol candidates of the estimate (the standard error of a
#: probability p from 256 draws is √(p(1 − p)/256) ≤ 0.031, 0.019 at p = 0.9).
SAMPLES = 256
CANDIDATES = 512


def regrets(model: PairwiseGP, data: PreferenceData, theta_star: list[float], seed: int,
            samples: int = SAMPLES, candidates: int = CANDIDATES) -> list[float]:
    """Per joint posterior draw, the regret of ``theta_star`` (the draw's maximum over the
    candidates minus its value at θ*), sorted: the share below ε is P(regret ≤ ε)."""
    X = torch.cat([torch.tensor(data.points, dtype=torch.float64).reshape(-1, data.dim),
                   torch.tensor([theta_star], dtype=torch.float64),
                   sobol_points(data.dim, seed, 0, candidates)])
    with torch.no_grad(), seeded(seed), expected_warnings(NumericalWarning, context="settled"):
        draws = model.posterior(X).rsample(torch.Size([samples])).reshape(samples, -1)
    regret = draws.max(dim=-1).values - draws[:, len(data.points)]
    return sorted(round(r, 6) for r in regret.clamp_min(0.0).tolist())
