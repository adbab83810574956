"""Eqs. (6)–(10) and the θ box of Table I."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from robot_io.config import DMPConstants
from robot_io.control.coupling import DistanceFilter, HandCoupling, sigmoid
from robot_io.errors import ConfigError, explain
from robot_io.theta import Theta


@pytest.mark.parametrize("y,a,delta", [(0.3, 13.0, -0.35), (-0.4, 5.0, 0.2), (0.0, 1.0, -1.0)])
def test_sigmoid_is_eq_10(y, a, delta):
    assert sigmoid(y, a, delta) == pytest.approx(1.0 / (1.0 + math.exp(-a * (y + delta))))


def test_sigmoid_is_half_at_minus_offset_and_stable_at_extremes():
    assert sigmoid(0.35, 13.0, -0.35) == 0.5
    assert sigmoid(1e6, 10.0, 0.0) == 1.0
    assert sigmoid(-1e6, 10.0, 0.0) == 0.0


def test_distance_filter_matches_eq_7_integrated_finely():
    """The exact (zero-order-hold) update equals a fine numerical solution of eq. (7)."""
    alpha, dt = 20.0, 0.008
    flt = DistanceFilter(alpha, dt)
    flt.reset(0.5)
    inputs = [0.5] * 5 + [0.3] * 40 + [0.6] * 40
    state = np.array([0.5, 0.0])
    for d in inputs:
        got = flt.update(d)
        state = solve_ivp(lambda _t, z, d=d: [z[1], alpha * (alpha / 4 * (d - z[0]) - z[1])],
                          (0, dt), state, rtol=1e-10, atol=1e-12).y[:, -1]
        np.testing.assert_allclose(got, state, atol=1e-8)


@given(alpha=st.floats(0.5, 200.0), dt=st.floats(1e-4, 0.05))
def test_the_closed_form_transition_is_the_matrix_exponential(alpha, dt):
    """eq. (7) discretised: the filter's closed-form A_d and B_d are exp(A·dt) and ∫exp(A·s)ds·b."""
    flt = DistanceFilter(alpha, dt)
    continuous = np.array([[0.0, 1.0], [-alpha**2 / 4, -alpha]])
    # the augmented exponential gives A_d and B_d together (Van Loan)
    augmented = np.zeros((3, 3))
    augmented[:2, :2], augmented[:2, 2] = continuous, [0.0, alpha**2 / 4]
    exact = expm(augmented * dt)
    np.testing.assert_allclose([[flt._a00, flt._a01], [flt._a10, flt._a11]], exact[:2, :2],
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose([flt._b0, flt._b1], exact[:2, 2], rtol=1e-9, atol=1e-12)


def test_filter_at_rest_stays_at_rest():
    flt = DistanceFilter(20.0, 0.002)
    flt.reset(0.42)
    for _ in range(100):
        value, rate = flt.update(0.42)
    assert value == pytest.approx(0.42) and rate == pytest.approx(0.0, abs=1e-12)


def test_coupling_terms_are_eq_8_and_9_with_k_t_equal_k_s(goal):
    constants, theta = DMPConstants(), Theta(a=5.0, delta=-0.2, k=15.0)
    coupling = HandCoupling(theta, goal, constants, dt=0.002)
    hand = goal + np.array([0.4, 0.0, 0.0])
    coupling.reset(hand)
    for i in range(30):  # the hand moves away at 0.5 m/s
        terms = coupling.update(hand + np.array([0.001 * i, 0.0, 0.0]))
    assert coupling.d0 == pytest.approx(0.4)
    sigma_d = 1 / (1 + math.exp(-13.0 * (coupling.d_filtered / 0.4 - 0.35)))
    sigma_j = 1 / (1 + math.exp(-5.0 * (coupling.d_rate - 0.2)))
    assert coupling.d_rate > 0
    assert terms.temporal == pytest.approx(15.0 * sigma_d * sigma_j)
    assert terms.spatial_gain == terms.temporal


def test_coupling_vanishes_when_the_hand_is_at_the_goal(goal):
    """σ_d(0) = 1/(1 + e^{13·0.35}) ≈ 0.0105: even k = 15 leaves C_t < 0.16 at the handover point."""
    coupling = HandCoupling(Theta(a=10.0, delta=1.0, k=15.0), goal, DMPConstants(), dt=0.002)
    coupling.reset(goal + np.array([0.5, 0.0, 0.0]))
    for _ in range(2000):
        terms = coupling.update(goal)
    assert coupling.sigma_d < 0.011
    assert terms.temporal < 15.0 * 0.011


def test_start_distance_is_guarded_against_zero(goal):
    coupling = HandCoupling(Theta(a=5.0, delta=0.0, k=1.0), goal, DMPConstants(), dt=0.002)
    coupling.reset(goal)  # hand starts at the handover point: d0 = 0
    assert coupling.d0 == DMPConstants().d0_min
    assert np.isfinite(coupling.update(goal).temporal)


@pytest.mark.parametrize("field,value,bounds", [
    ("a", 0.5, "[1.0, 10.0]"), ("a", 10.5, "[1.0, 10.0]"), ("delta", -1.01, "[-1.0, 1.0]"),
    ("k", 0.0, "[0.01, 15.0]"), ("k", 15.5, "[0.01, 15.0]"), ("k", float("nan"), "[0.01, 15.0]"),
])
def test_theta_out_of_box_is_an_error_naming_field_value_and_range(field, value, bounds):
    values = {"a": 5.0, "delta": 0.0, "k": 1.0, field: value}
    with pytest.raises(ValidationError) as info:
        Theta(**values)
    message = explain(info.value)
    assert f"theta.{field} = {value!r}" in message and bounds in message


def test_theta_box_edges_are_allowed_and_never_clipped():
    theta = Theta(a=1.0, delta=-1.0, k=0.01)
    assert theta.as_tuple() == (1.0, -1.0, 0.01)
    assert Theta.parse(" 10, 1, 15 ").as_tuple() == (10.0, 1.0, 15.0)


@pytest.mark.parametrize("text", ["1,2", "a,b,c", "1,2,3,4", ""])
def test_theta_parse_rejects_malformed_text(text):
    with pytest.raises(ConfigError, match="three numbers"):
        Theta.parse(text)
