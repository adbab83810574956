"""Coupling of the DMP to the tracked hand, eqs. (6)–(10), after Sect. III-B (docs/controller.md).

    d  = ‖g − x_hand‖                                  (6)
    d̃̈ = α_d(α_d/4 (d − d̃) − d̃̇)                       (7)   d̃(0) = d(0), d̃̇(0) = 0
    C_t = k_t σ_d(d̃/d0) σ_j(d̃̇)                         (8)
    C_s = −α_x τ ẋ k_s σ_d(d̃/d0) σ_j(d̃̇)                (9)
    σ_i(y) = 1 / (1 + exp(−a_i(y + δ_i)))               (10)

σ_d is fixed (Table I: a = 13.0, δ = −0.35); σ_j takes the learned θ = (a, δ, k), with k_t = k_s = k.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from robot_io.config import DMPConstants
from robot_io.control.dmp import NO_COUPLING, CouplingTerms
from robot_io.theta import Theta
from robot_io.vector import norm


def sigmoid(y: float, a: float, delta: float) -> float:
    """σ(y) = 1/(1 + exp(−a(y + δ))), eq. (10), without overflow for any finite input."""
    z = a * (y + delta)
    if z >= 0:
        return 1.0 / (1.0 + math.exp(-z))
    e = math.exp(z)
    return e / (1.0 + e)


class DistanceFilter:
    """The critically damped second-order low-pass filter of eq. (7), discretised exactly.

    The input d is held constant over each step (zero-order hold), so the update
    [d̃, d̃̇] ← A_d [d̃, d̃̇] + B_d d is exact for any step length. The system matrix
    A = [[0, 1], [−ω², −2ω]] with ω = α_d/2 has the double eigenvalue −ω (critical damping), so
    A_d = exp(A·dt) = e^(−ω·dt) [[1 + ω·dt, dt], [−ω²·dt, 1 − ω·dt]] in closed form, and
    B_d = A⁻¹(A_d − I)[0, ω²]ᵀ.
    """

    def __init__(self, alpha_d: float, dt: float) -> None:
        omega = alpha_d / 2.0
        continuous = np.array([[0.0, 1.0], [-omega**2, -2.0 * omega]])
        transition = math.exp(-omega * dt) * np.array([[1.0 + omega * dt, dt],
                                                       [-omega**2 * dt, 1.0 - omega * dt]])
        gain = np.linalg.solve(continuous, (transition - np.eye(2)) @ np.array([0.0, alpha_d**2 / 4]))
        (self._a00, self._a01), (self._a10, self._a11) = transition.tolist()
        self._b0, self._b1 = gain.tolist()
        self.value = 0.0
        self.rate = 0.0

    def reset(self, d: float) -> None:
        self.value, self.rate = d, 0.0

    def update(self, d: float) -> tuple[float, float]:
        """One step with input d; returns (d̃, d̃̇)."""
        value, rate = self.value, self.rate
        self.value = self._a00 * value + self._a01 * rate + self._b0 * d
        self.rate = self._a10 * value + self._a11 * rate + self._b1 * d
        return self.value, self.rate


class Coupling(Protocol):
    """What the control loop needs of a coupling: start it on the first hand sample, then update it
    once per cycle with the latest hand position."""

    def reset(self, hand: np.ndarray) -> None: ...

    def update(self, hand: np.ndarray) -> CouplingTerms: ...


class NoCoupling:
    """The uncoupled DMP: C_t = C_s = 0."""

    def reset(self, hand: np.ndarray) -> None:
        pass

    def update(self, hand: np.ndarray) -> CouplingTerms:
        return NO_COUPLING


class HandCoupling:
    """Eqs. (6)–(10): the DMP slows down (C_t) and is damped (C_s) when the hand moves away or waits.

    After each :meth:`update` the attributes ``d``, ``d_filtered``, ``d_rate``, ``sigma_d``,
    ``sigma_j`` and ``c_t`` hold the values of this cycle, for the record.
    """

    def __init__(self, theta: Theta, goal: np.ndarray, constants: DMPConstants, dt: float) -> None:
        self.theta = theta
        self.goal = np.asarray(goal, dtype=float)
        self.constants = constants
        self.filter = DistanceFilter(constants.alpha_d, dt)
        self.d0 = self.d = self.d_filtered = self.d_rate = 0.0
        self.sigma_d = self.sigma_j = self.c_t = 0.0

    def distance(self, hand: np.ndarray) -> float:
        """d = ‖g − x_hand‖₂, eq. (6)."""
        return norm(self.goal - hand)

    def reset(self, hand: np.ndarray) -> None:
        """Start of the interaction: d0 = d(t0) (at least ``d0_min``), d̃(0) = d0, d̃̇(0) = 0."""
        self.d = self.distance(hand)
        self.d0 = max(self.d, self.constants.d0_min)
        self.filter.reset(self.d)
        self.d_filtered, self.d_rate = self.d, 0.0

    def update(self, hand: np.ndarray) -> CouplingTerms:
        c, theta = self.constants, self.theta
        self.d = self.distance(hand)
        self.d_filtered, self.d_rate = self.filter.update(self.d)
        self.sigma_d = sigmoid(self.d_filtered / self.d0, c.sigma_d_a, c.sigma_d_delta)
        self.sigma_j = sigmoid(self.d_rate, theta.a, theta.delta)
        self.c_t = theta.k * self.sigma_d * self.sigma_j  # (8); k_s = k_t = k in (9)
        return CouplingTerms(temporal=self.c_t, spatial_gain=self.c_t)
