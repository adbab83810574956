"""Multi-DOF discrete DMP with coupling terms, eqs. (1)–(5), stepped online.

    τ²ẍ = α_x(β_x(g − x) − τẋ) + f(s) + C_s + k_ext F    (1), (4)
    τṡ  = −α_s s                                    (3)
    τ   = τ0(1 + C_t)                               (5)

with C_s = −α_x τ ẋ γ (eq. 9, γ = k_s σ_d σ_j given by the coupling) and k_ext F the external-force
term of Table I (docs/controller.md; zero unless a compliance coupling supplies it). All DOFs share the
phase s.
The phase is integrated online: τ changes every step, so s is never computed in closed form from t.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from robot_io.config import DMPConstants
from robot_io.control.forcing import ForcingTerm
from robot_io.minimum_jerk import minimum_jerk


class CouplingTerms(NamedTuple):
    """What a coupling contributes to one DMP step.

    ``temporal`` is C_t of eq. (5); ``spatial_gain`` is γ such that C_s = −α_x τ ẋ γ (eq. 9);
    ``external`` is k_ext·F, the measured pull times k_ext, added to τ²ẍ (None: no such term).
    """

    temporal: float = 0.0
    spatial_gain: float = 0.0
    external: np.ndarray | None = None


NO_COUPLING = CouplingTerms()


class DMP:
    """A discrete DMP for ``len(start)`` DOFs, stepped with :meth:`step`.

    Each step integrates eqs. (1), (3)–(5) over ``dt`` with RK4, holding τ and the coupling constant
    over the step; the phase stages are exact for constant τ: s(t+h) = s(t)·exp(−α_s h/τ).
    """

    def __init__(self, start: np.ndarray, goal: np.ndarray, forcing: ForcingTerm,
                 constants: DMPConstants) -> None:
        self.start = np.asarray(start, dtype=float).copy()
        self.goal = np.asarray(goal, dtype=float).copy()
        self.forcing = forcing
        self.constants = constants
        self.reset()

    @classmethod
    def from_demonstration(cls, t: np.ndarray, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                           constants: DMPConstants) -> DMP:
        """Fit the forcing term to a demonstration (times, positions, velocities, accelerations).

        The target is f(t) = τ0²ẍ − α_x(β_x(g − x) − τ0ẋ), eq. (1) solved for f with no coupling, at the
        phase s(t) = exp(−α_s t/τ0) of eq. (3).
        """
        c = constants
        start, goal = x[0], x[-1]
        centers, widths = ForcingTerm.basis_for(c.n_basis, c.alpha_s, float(t[-1] - t[0]), c.tau0)
        forcing = ForcingTerm(centers, widths, np.zeros((c.n_basis, x.shape[1])), goal - start)
        f_target = c.tau0**2 * xdd - c.alpha_x * (c.beta_x * (goal - x) - c.tau0 * xd)
        forcing.fit(np.exp(-c.alpha_s * (t - t[0]) / c.tau0), f_target)
        return cls(start, goal, forcing, constants)

    @classmethod
    def from_minimum_jerk(cls, start: np.ndarray, goal: np.ndarray, constants: DMPConstants,
                          samples: int = 1000) -> DMP:
        """The default DMP: fitted to a minimum-jerk reach of duration τ0 from start to goal,
        followed by rest until ``constants.demo_fit_duration``."""
        t = np.linspace(0.0, constants.demo_fit_duration, samples)
        return cls.from_demonstration(t, *minimum_jerk(start, goal, constants.tau0, t), constants)

    def reset(self) -> None:
        """Back to the start: x = x0, ẋ = 0, s = 1, τ = τ0, t = 0."""
        self.x = self.start.copy()
        self.xd = np.zeros_like(self.start)
        self.xdd = np.zeros_like(self.start)
        self.s = 1.0
        self.t = 0.0
        self.tau = self.constants.tau0
        self.c_s = np.zeros_like(self.start)

    def step(self, dt: float, coupling: CouplingTerms = NO_COUPLING) -> np.ndarray:
        """Advance by ``dt`` under the given coupling; returns the new position x.

        The DOFs share τ, the phase and the gains, so RK4 runs on each DOF's floats: NumPy's
        per-call cost on 3-element arrays was most of a step (the same IEEE operations, so the same
        numbers to the last bit).
        """
        c = self.constants
        tau = c.tau0 * (1.0 + coupling.temporal)  # (5)
        stiffness = c.alpha_x * c.beta_x / tau**2
        damping = c.alpha_x * (1.0 + coupling.spatial_gain) / tau  # (1) + C_s of (9), over τ²
        s_half = self.s * math.exp(-c.alpha_s * 0.5 * dt / tau)  # (3), exact for constant τ
        s_end = self.s * math.exp(-c.alpha_s * dt / tau)
        forcing = (self.forcing(np.array([self.s, s_half, s_end])) / tau**2).T.tolist()
        pull = stiffness * self.goal
        if coupling.external is not None:
            pull = pull + coupling.external / tau**2  # k_ext F, constant over the step

        h = 0.5 * dt
        positions, velocities, accelerations = [], [], []
        for x, v, p, (f0, f_half, f_end) in zip(self.x.tolist(), self.xd.tolist(), pull.tolist(),
                                                forcing, strict=True):
            a1 = p - stiffness * x - damping * v + f0
            x2, v2 = x + h * v, v + h * a1
            a2 = p - stiffness * x2 - damping * v2 + f_half
            x3, v3 = x + h * v2, v + h * a2
            a3 = p - stiffness * x3 - damping * v3 + f_half
            x4, v4 = x + dt * v3, v + dt * a3
            a4 = p - stiffness * x4 - damping * v4 + f_end
            positions.append(x + dt / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4))
            velocities.append(v + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4))
            accelerations.append(a4)

        self.x, self.xd, self.xdd = np.array(positions), np.array(velocities), np.array(accelerations)
        self.c_s = -c.alpha_x * tau * self.xd * coupling.spatial_gain  # (9), for the record
        self.s = s_end
        self.tau = tau
        self.t += dt
        return self.x
