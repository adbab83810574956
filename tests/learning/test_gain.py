"""What the next batch may gain over θ* (app.learning.gain) and the rule that stops on it
(GainRule, ``[protocol] stop_when_no_gain``); the simulated participant's wrong and misread hints."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.stats import norm

from app.learning.acquisition import sobol_points
from app.learning.coactive import HintDirection
from app.learning.config import GainRule, LearnerConfig, epsilon_for
from app.learning.learner import PreferenceLearner
from app.learning.models import NextBatchGain, ParameterBox
from app.learning.planner import BatchSchedule
from app.learning.simulation import (
    STUDY_MODEL,
    STUDY_OPTIMIZER,
    StudyCondition,
    participant_hint,
)

from .conftest import TABLE_I, drive


@pytest.fixture(scope="module")
def learned():
    """A learner on Table I's box after its initial batch and one learning batch (q = 3; the
    simulated study's fit and search settings, which are quicker)."""
    learner = PreferenceLearner(LearnerConfig(
        box=ParameterBox.from_bounds(TABLE_I), schedule=BatchSchedule(n_initial=4, q=3, n_unique=10),
        model=STUDY_MODEL, optimizer=STUDY_OPTIMIZER, seed=5))
    drive(learner, 7)
    return learner


def closed_form_gain(model, x: torch.Tensor, star: torch.Tensor) -> np.ndarray:
    """E[(u(x) − u(θ*))⁺] of each row of ``x`` from the joint Gaussian posterior of (u(x), u(θ*)):
    s·φ(m/s) + m·Φ(m/s), m the mean and s the standard deviation of the difference."""
    with torch.no_grad():
        posterior = model.posterior(torch.stack([x, star.expand_as(x)], dim=-2))
        mean = posterior.mean.squeeze(-1).numpy()
        cov = posterior.covariance_matrix.numpy()
    m = mean[:, 0] - mean[:, 1]
    s = np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1] - 2 * cov[:, 0, 1], 1e-12))
    return s * norm.pdf(m / s) + m * norm.cdf(m / s)


def test_the_gain_is_the_expected_advantage_of_the_best_next_handover_over_theta_star(learned):
    gain = learned.expected_gain()
    box, model = learned.config.box, learned.model.model
    assert gain is not None and gain.queries == 2 and gain.theta == learned.best().theta
    star = torch.tensor(box.to_unit(gain.theta), dtype=torch.float64)
    x = torch.tensor(box.to_unit(gain.candidate), dtype=torch.float64)
    # E[(u(θ) − u(θ*))⁺] at the candidate: the closed form, and joint posterior draws
    assert gain.gain == pytest.approx(float(closed_form_gain(model, x[None], star)[0]), rel=1e-6)
    torch.manual_seed(0)
    draws = model.posterior(torch.stack([x, star])).rsample(torch.Size([200_000])).reshape(-1, 2)
    assert gain.gain == pytest.approx(float((draws[:, 0] - draws[:, 1]).clamp_min(0).mean()),
                                      rel=0.03)
    # the largest over the box: no point of a Sobol design of the box gains more
    design = sobol_points(3, 11, 0, 256)
    assert float(closed_form_gain(model, design, star).max()) <= gain.gain * (1 + 1e-3)
    assert gain.gain > 0.0


def test_the_chance_bounds_what_the_next_batch_may_find(learned):
    """Markov's inequality per handover: P(u(θ) − u(θ*) > ε) ≤ g/ε, here at the candidate."""
    gain = learned.expected_gain()
    box, model = learned.config.box, learned.model.model
    star = torch.tensor(box.to_unit(gain.theta), dtype=torch.float64)
    x = torch.tensor(box.to_unit(gain.candidate), dtype=torch.float64)
    torch.manual_seed(1)
    draws = model.posterior(torch.stack([x, star])).rsample(torch.Size([100_000])).reshape(-1, 2)
    for preference in (0.55, 0.6, 0.8):
        epsilon = epsilon_for(preference)
        found = float(((draws[:, 0] - draws[:, 1]) > epsilon).double().mean())
        assert found <= gain.chance(epsilon) / gain.queries + 0.01
        assert gain.chance(epsilon) == pytest.approx(min(1.0, 2 * gain.gain / epsilon))


def test_the_gain_rule_stops_once_the_next_batch_is_unlikely_to_find_better():
    rule = GainRule(chance=0.2, preference=0.6, min_batches=2)
    epsilon = epsilon_for(0.6)
    at = {"x": 0.5}

    def gain(chance: float) -> NextBatchGain:  # the gain whose chance is ``chance``
        return NextBatchGain(gain=chance * epsilon / 4, queries=4, theta=at, candidate=at)

    assert rule.epsilon == pytest.approx(math.sqrt(2) * norm.ppf(0.6))
    assert rule.stops(2, gain(0.2)) and rule.stops(3, gain(0.05))
    assert not rule.stops(2, gain(0.21)) and not rule.stops(1, gain(0.0)) and not rule.stops(
        5, None)
    assert gain(3.0).chance(epsilon) == 1.0  # a bound on a probability


@pytest.mark.parametrize("field,value", [("chance", 0.0), ("chance", 1.0), ("preference", 0.5),
                                         ("min_batches", 0)])
def test_a_gain_rule_out_of_range_names_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        GainRule(**{field: value})


# The simulated participant's mistakes (issue 46, goal 3)

UNIT = ParameterBox.unit_cube(3)
THETA = {"x1": 0.5, "x2": 0.5, "x3": 0.5}
HONEST = StudyCondition(noise=0.01, coactive=True)


def distance_to(target: np.ndarray):
    return lambda theta: float(np.linalg.norm(target - np.array([theta[n] for n in UNIT.names])))


def test_a_wrong_hint_points_the_other_way_with_the_same_felt_noise():
    utility = distance_to(np.array([0.5, 1.0, 0.5]))  # later (x2 up) feels better
    later = HintDirection(parameter="x2", sign=1)
    flips = HONEST.model_copy(update={"hint_flip": 1.0})
    for seed in range(5):
        honest = participant_hint(HONEST, UNIT, THETA, utility, np.random.default_rng(seed),
                                  np.random.default_rng(99))
        wrong = participant_hint(flips, UNIT, THETA, utility, np.random.default_rng(seed),
                                 np.random.default_rng(99))
        assert honest == later and wrong == HintDirection(parameter="x2", sign=-1)


def test_sooner_read_as_faster_is_said_when_a_faster_robot_would_be_better():
    """Only x1 up (the a analogue, no word on the tablet) feels better: an honest participant
    says nothing, one who reads "sooner" as "faster" says "sooner" (x2 down) every time."""
    utility = distance_to(np.array([0.9, 0.5, 0.5]))
    faster = HONEST.model_copy(update={"hint_faster": 1.0})
    sooner = HintDirection(parameter="x2", sign=-1)
    for seed in range(5):
        assert participant_hint(HONEST, UNIT, THETA, utility, np.random.default_rng(seed)) is None
        assert participant_hint(faster, UNIT, THETA, utility,
                                np.random.default_rng(seed)) == sooner
    half = HONEST.model_copy(update={"hint_faster": 0.5})
    said = [participant_hint(half, UNIT, THETA, utility, np.random.default_rng(seed),
                             np.random.default_rng(1000 + seed)) for seed in range(400)]
    assert 0.4 < said.count(sooner) / len(said) < 0.6
