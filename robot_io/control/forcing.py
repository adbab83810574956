"""The DMP forcing term f(s) = f_nl(s)·s·(g − x0) of eq. (2), with f_nl a normalised Gaussian basis.

f_nl(s) = Σ_i w_i ψ_i(s) / Σ_i ψ_i(s),  ψ_i(s) = exp(−h_i (s − c_i)²), one weight column per DOF.
The weights are fitted by (ridge-regularised) least squares to the forcing term that a demonstration
implies under eq. (1) with τ = τ0 and no coupling.
"""

from __future__ import annotations

import numpy as np


class ForcingTerm:
    """Gaussian-basis forcing term of eq. (2) for ``dim`` DOFs sharing one phase."""

    def __init__(self, centers: np.ndarray, widths: np.ndarray, weights: np.ndarray,
                 scale: np.ndarray) -> None:
        self.centers = np.asarray(centers, dtype=float)
        self.widths = np.asarray(widths, dtype=float)
        self._negative_widths = -self.widths  # features() runs every control cycle
        self.weights = np.asarray(weights, dtype=float)  # (n_basis, dim)
        self.scale = np.asarray(scale, dtype=float)  # (g − x0), shape (dim,)

    @staticmethod
    def basis_for(n_basis: int, alpha_s: float, duration: float, tau0: float) -> tuple[
            np.ndarray, np.ndarray]:
        """Centres equally spaced in time over ``duration`` (so in phase s = exp(−α_s t/τ0), eq. 3),
        widths from the spacing of neighbouring centres."""
        centers = np.exp(-alpha_s * np.linspace(0.0, duration, n_basis) / tau0)
        gaps = np.abs(np.diff(centers))
        widths = 1.0 / np.append(gaps, gaps[-1]) ** 2
        return centers, widths

    def features(self, s: np.ndarray) -> np.ndarray:
        """Φ(s)_i = ψ_i(s) s / Σ_j ψ_j(s), shape ``(len(s), n_basis)``; f(s) = Φ(s) W ⊙ (g − x0)."""
        s = np.atleast_1d(s)
        psi = np.exp(self._negative_widths * np.square(s[:, None] - self.centers))
        return psi * (s / (psi.sum(axis=1) + 1e-300))[:, None]

    def __call__(self, s: np.ndarray) -> np.ndarray:
        """f(s) for each phase value in ``s``: shape ``(len(s), dim)`` (eq. 2)."""
        return (self.features(s) @ self.weights) * self.scale

    def fit(self, s: np.ndarray, f_target: np.ndarray, ridge: float = 1e-9) -> None:
        """Least-squares weights so that f(s) ≈ ``f_target`` (shape ``(len(s), dim)``).

        A DOF that does not move (g − x0 ≈ 0) gets zero weights: its forcing term vanishes.
        """
        phi = self.features(s)
        gram = phi.T @ phi + ridge * np.eye(phi.shape[1])
        moving = np.abs(self.scale) > 1e-9
        target = np.zeros_like(f_target)
        target[:, moving] = f_target[:, moving] / self.scale[moving]
        self.weights = np.linalg.solve(gram, phi.T @ target)
