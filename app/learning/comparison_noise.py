"""Comparisons that are not equally reliable: the batch position of eq. (16) in the likelihood.

Eq. (16) observes the j-th interaction of a batch as y = u + j·N(0, σ²): later interactions of a
batch are remembered less reliably, so a comparison between positions i and j has noise of SD
σ·√(i² + j²). BoTorch's ``PairwiseProbitLikelihood`` gives every comparison the same noise,
P(θ_w ≻ θ_l) = Φ((f_w − f_l)/√2), and so trusts a comparison of a batch's last two handovers as much
as one against the handover that opened it. :class:`BatchPositionProbit` divides each comparison's
z by its relative noise s = √((i² + j²)/2) (1 for two first positions):
P = Φ((f_w − f_l)/(√2·s)). The kernel's output scale, fitted as before, sets the overall level.

BoTorch's probit is linear in the rows of the comparison matrix D (z = D f/√2, gradient −hᵀD/√2,
Hessian Dᵀ diag(h(h + z)/2) D), so dividing row k of D by s_k gives exactly this likelihood and its
derivatives for the Laplace approximation of eq. (13) and the marginal likelihood.

Each comparison may also carry a weight w_k, its exponent in the likelihood, Φ(z_k)^{w_k}: the log
likelihood, its gradient and its Hessian are then sums weighted by w_k. A comparison weighs 1; the
two halves of a tie (:mod:`app.learning.ties`) weigh ½ each.
"""

from __future__ import annotations

import math

import torch
from botorch.models.likelihoods.pairwise import PairwiseProbitLikelihood


def relative_noise(position_winner: int, position_loser: int) -> float:
    """s = √((i² + j²)/2) of a comparison between batch positions i and j (eq. (16))."""
    return math.sqrt((position_winner ** 2 + position_loser ** 2) / 2.0)


class BatchPositionProbit(PairwiseProbitLikelihood):
    """The probit likelihood with one relative noise per comparison (in the order of ``D``'s rows)
    and, optionally, one weight per comparison (default 1)."""

    def __init__(self, scales: torch.Tensor, weights: torch.Tensor | None = None) -> None:
        super().__init__()
        if scales.ndim != 1 or bool((scales <= 0).any()):
            raise ValueError("scales must be a vector of positive relative noises, one per comparison")
        if weights is not None and (weights.shape != scales.shape or bool((weights <= 0).any())):
            raise ValueError("weights must be a vector of positive weights, one per comparison")
        self.scales = scales
        self.weights = torch.ones_like(scales) if weights is None else weights

    def _scaled(self, D: torch.Tensor) -> torch.Tensor:
        if D.shape[-2] != self.scales.shape[0]:
            raise ValueError(f"D has {D.shape[-2]} comparisons but {self.scales.shape[0]} scales")
        return D / self.scales.to(D).unsqueeze(-1)

    def p(self, utility: torch.Tensor, D: torch.Tensor, log: bool = False) -> torch.Tensor:
        return super().p(utility, self._scaled(D), log) ** self.weights.to(utility)

    def negative_log_gradient_sum(self, utility: torch.Tensor, D: torch.Tensor) -> torch.Tensor:
        D = self._scaled(D)
        _, _, h = self._calc_z_derived(self._calc_z(utility, D))
        factor = self.weights.to(h) * h / math.sqrt(2)
        return (factor.unsqueeze(-2) @ (-D)).squeeze(-2)

    def negative_log_hessian_sum(self, utility: torch.Tensor, D: torch.Tensor) -> torch.Tensor:
        D = self._scaled(D)
        z = self._calc_z(utility, D)
        _, _, h = self._calc_z_derived(z)
        factor = (self.weights.to(h) * h * (h + z) / 2).unsqueeze(-2)
        return D.transpose(-1, -2) * factor @ D
