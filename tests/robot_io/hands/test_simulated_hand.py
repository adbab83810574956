"""The simulated participant's hand: the two scenarios, seeding, tracker rate, noise and dropouts."""

from __future__ import annotations

import numpy as np
import pytest

from robot_io.config import HandProfile
from robot_io.errors import ConfigError
from robot_io.hands.simulated_hand import Scenario, SimulatedHand


def test_same_seed_same_trajectory_other_seed_other_timing(config):
    a = SimulatedHand(Scenario.PERTURBED, config.scene, config.hand, seed=3)
    b = SimulatedHand(Scenario.PERTURBED, config.scene, config.hand, seed=3)
    c = SimulatedHand(Scenario.PERTURBED, config.scene, config.hand, seed=4)
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.arrival_time != c.arrival_time


def test_straightforward_reach_goes_from_a_to_h_after_the_reaction_delay(config):
    hand = SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, config.hand, seed=1)
    low, high = config.hand.reaction_delay_s
    assert low <= hand.reaction_delay <= high
    np.testing.assert_allclose(hand.position_at(0.0), config.scene.hand_start)
    np.testing.assert_allclose(hand.position_at(hand.reaction_delay), config.scene.hand_start)
    np.testing.assert_allclose(hand.position_at(hand.arrival_time), config.scene.handover_point)
    length = np.linalg.norm(config.scene.point("handover_point") - config.scene.point("hand_start"))
    speed = length / (hand.arrival_time - hand.reaction_delay)
    assert config.hand.mean_speed_mps[0] <= speed <= config.hand.mean_speed_mps[1]


def test_perturbed_visits_the_box_then_the_place_then_h_with_pauses(config):
    hand = SimulatedHand(Scenario.PERTURBED, config.scene, config.hand, seed=2)
    (_, b1, _, box), (c0, c1, _, _), (h0, _, _, goal) = hand.segments
    np.testing.assert_allclose(hand.position_at(b1), config.scene.box)
    np.testing.assert_allclose(hand.position_at(c1), config.scene.place)
    assert config.hand.pause_s[0] <= c0 - b1 <= config.hand.pause_s[1]
    assert config.hand.pause_s[0] <= h0 - c1 <= config.hand.pause_s[1]
    # the default box sits about 25 cm from the handover point (Sect. V-A)
    assert np.linalg.norm(box - goal) == pytest.approx(0.25, abs=0.03)


def test_samples_arrive_at_the_tracker_rate(config):
    hand = SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, config.hand, seed=1)
    assert np.diff(hand.times) == pytest.approx(0.01)
    assert hand.latest(0.0259).t == pytest.approx(0.02)
    assert hand.latest(-0.001) is None


def test_noise_and_dropouts(config):
    profile = HandProfile(noise_std_m=0.002, dropout_rate=0.3)
    clean = SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, config.hand, seed=5)
    noisy = SimulatedHand(Scenario.STRAIGHTFORWARD, config.scene, profile, seed=5)
    residual = (noisy.positions - clean.positions).ravel()
    assert residual.std() == pytest.approx(0.002, rel=0.1)
    assert 0.25 < 1 - noisy.delivered.mean() < 0.35
    lost = int(np.flatnonzero(~noisy.delivered)[0])
    newest = noisy.latest(noisy.times[lost])
    assert newest.t < noisy.times[lost]  # a lost sample leaves the previous one as the newest


def test_hand_profile_ranges_are_validated():
    with pytest.raises(ValueError, match="reaction_delay_s"):
        HandProfile(reaction_delay_s=(0.5, 0.1))
    with pytest.raises(ConfigError, match="scenario = 'sideways' is not one of"):
        Scenario.parse("sideways")
