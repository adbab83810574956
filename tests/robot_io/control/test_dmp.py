"""The DMP of eqs. (1)–(5) against its demonstration and against the time scaling of eqs. (3), (5)."""

from __future__ import annotations

import numpy as np
import pytest

from robot_io.config import DMPConstants
from robot_io.control.dmp import DMP, NO_COUPLING, CouplingTerms
from robot_io.minimum_jerk import minimum_jerk


def rollout(dmp: DMP, rate: int, seconds: float, coupling: CouplingTerms = NO_COUPLING):
    n = round(seconds * rate)
    t, x, s = np.zeros(n), np.zeros((n, 3)), np.zeros(n)
    for i in range(n):
        dmp.step(1.0 / rate, coupling)
        t[i], x[i], s[i] = dmp.t, dmp.x, dmp.s
    return t, x, s


@pytest.mark.parametrize("rate", [125, 500])
def test_uncoupled_dmp_reproduces_minimum_jerk_demonstration_within_1mm(start, goal, rate):
    constants = DMPConstants()
    t, x, _ = rollout(DMP.from_minimum_jerk(start, goal, constants), rate, 3.0)
    demo, _, _ = minimum_jerk(start, goal, constants.tau0, t)
    assert np.linalg.norm(x - demo, axis=1).max() < 1e-3


def test_uncoupled_dmp_converges_to_goal_without_overshoot(start, goal):
    _, x, _ = rollout(DMP.from_minimum_jerk(start, goal, DMPConstants()), 500, 4.0)
    path = goal - start
    progress = (x - start) @ path / np.linalg.norm(path)
    # 10 µm: the residual of the fitted forcing term, a tenth of a UR5's repeatability.
    assert progress.max() - np.linalg.norm(path) < 1e-5
    assert np.linalg.norm(x[-1] - goal) < 1e-4


def test_other_demonstration_is_reproduced(start, goal):
    """A demonstration that is not a straight line (a lift through a via point) is fitted too."""
    constants = DMPConstants()
    t = np.linspace(0, constants.demo_fit_duration, 1000)
    lift = np.sin(np.pi * np.clip(t / constants.tau0, 0, 1))[:, None] ** 2 * np.array([0, 0, 0.1])
    pos, vel, acc = minimum_jerk(start, goal, constants.tau0, t)
    u = np.clip(t / constants.tau0, 0, 1)
    lift_v = (np.pi / constants.tau0) * np.sin(2 * np.pi * u)[:, None] * np.array([0, 0, 0.1])
    lift_a = (2 * np.pi**2 / constants.tau0**2) * np.cos(2 * np.pi * u)[:, None] * np.array(
        [0, 0, 0.1]) * (t < constants.tau0)[:, None]
    dmp = DMP.from_demonstration(t, pos + lift, vel + lift_v, acc + lift_a, constants)
    t_run, x, _ = rollout(dmp, 500, 1.2)
    expected = np.array([np.interp(t_run, t, (pos + lift)[:, i]) for i in range(3)]).T
    assert np.linalg.norm(x - expected, axis=1).max() < 2e-3


def test_phase_is_integrated_online_with_tau_from_the_temporal_coupling(start, goal):
    """Eqs. (3), (5): with C_t = 1 held, τ = 2τ0 and s(t) = exp(−α_s t / (2τ0))."""
    constants = DMPConstants()
    t, _, s = rollout(DMP.from_minimum_jerk(start, goal, constants), 500, 1.0, CouplingTerms(1.0))
    np.testing.assert_allclose(s, np.exp(-constants.alpha_s * t / (2 * constants.tau0)), rtol=1e-9)


def test_temporal_coupling_alone_slows_the_movement_uniformly(start, goal):
    """τ = 2τ0 with no spatial term runs the same path at half speed: x_c(2t) = x_u(t)."""
    constants = DMPConstants()
    _, x_u, _ = rollout(DMP.from_minimum_jerk(start, goal, constants), 500, 1.5)
    _, x_c, _ = rollout(DMP.from_minimum_jerk(start, goal, constants), 500, 3.0, CouplingTerms(1.0))
    assert np.linalg.norm(x_c[1::2] - x_u, axis=1).max() < 1e-4


def test_spatial_coupling_is_the_damping_term_of_eq_9(start, goal):
    """C_s = −α_x τ ẋ γ: recorded per step, and it holds the robot back compared with C_t alone."""
    constants = DMPConstants()
    only_t = DMP.from_minimum_jerk(start, goal, constants)
    both = DMP.from_minimum_jerk(start, goal, constants)
    for _ in range(250):
        only_t.step(0.002, CouplingTerms(1.0, 0.0))
        both.step(0.002, CouplingTerms(1.0, 1.0))
    np.testing.assert_allclose(both.c_s, -constants.alpha_x * both.tau * both.xd * 1.0)
    assert np.linalg.norm(both.x - start) < np.linalg.norm(only_t.x - start)
