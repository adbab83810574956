"""The external-force term of Table I: while the participant holds the object, the measured pull
times k_ext enters the DMP acceleration (docs/controller.md), so the arm yields like a virtual spring
instead of resisting the pull.

    τ²ẍ = … + k_ext (F − F₀)        F₀: the baseline force at grasp

:class:`CompliantCoupling` wraps any coupling and adds the term while ``grasped()`` is true.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from robot_io.control.coupling import Coupling, HandCoupling
from robot_io.control.dmp import CouplingTerms


class CompliantCoupling:
    """``inner``'s terms plus ``external = k_ext (F − F₀)`` while grasped."""

    def __init__(self, inner: Coupling, read_force: Callable[[], np.ndarray], k_ext: float,
                 grasped: Callable[[], bool], baseline: Callable[[], np.ndarray | None]) -> None:
        self.inner, self.read_force, self.k_ext = inner, read_force, k_ext
        self.grasped, self.baseline = grasped, baseline

    @property
    def hand_coupling(self) -> HandCoupling | None:
        """The coupling to the hand (eqs. 5–10) under the compliance term, whose signals the loop
        records (None if ``inner`` is another kind of coupling)."""
        return signals_source(self.inner)

    def reset(self, hand: np.ndarray) -> None:
        self.inner.reset(hand)

    def update(self, hand: np.ndarray) -> CouplingTerms:
        terms = self.inner.update(hand)
        baseline = self.baseline()
        if not self.grasped() or baseline is None:
            return terms
        return terms._replace(external=self.k_ext * (self.read_force() - baseline))


def signals_source(coupling: Coupling) -> HandCoupling | None:
    """The :class:`HandCoupling` whose d, d̃, d̃̇, σ_d, σ_j and C_t (eqs. 5–10) a trial records:
    ``coupling`` itself, or the one a :class:`CompliantCoupling` wraps; None for any other."""
    if isinstance(coupling, CompliantCoupling):
        return coupling.hand_coupling
    return coupling if isinstance(coupling, HandCoupling) else None
