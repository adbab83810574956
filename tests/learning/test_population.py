"""Priors from earlier participants: the pooled mean is their posterior mean, data override it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from app.learning.config import LearnerConfig
from app.learning.errors import LearningError
from app.learning.learner import PreferenceLearner
from app.learning.models import Interaction, ParameterBox
from app.learning.pooled_prior import population_prior
from app.learning.population import DISTINCT_FAVOURITES, PopulationMean
from app.learning.preference_model import posterior_at
from app.learning.simulation import participant_target

from .conftest import TABLE_I, drive


@pytest.fixture(scope="module")
def earlier():
    """Two earlier participants (same box and target)."""
    snapshots = {}
    for seed in (1, 2):
        learner = PreferenceLearner(LearnerConfig(box=ParameterBox.from_bounds(TABLE_I),
                                                  seed=seed))
        drive(learner, 10)
        snapshots[f"P0{seed}"] = learner.snapshot()
    return snapshots


def test_the_pooled_mean_is_the_average_of_the_earlier_posterior_means(earlier):
    """The first of the module's tests builds ``earlier``: two participants of 10 interactions
    each through the real learner (a GP fit and an acquisition optimisation each), up to 25 s on
    a loaded machine."""
    X = torch.rand(7, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    means = [posterior_at(PreferenceLearner.restore(s).model.model, X)[0]
             for s in earlier.values()]
    prior = population_prior(earlier, weight=0.5)
    assert prior.sources == ["P01", "P02"]
    expected = 0.5 * (means[0] + means[1]) / 2
    assert PopulationMean(prior)(X) == pytest.approx(expected, rel=1e-6, abs=1e-8)


def test_a_new_participant_starts_from_the_prior_and_records_its_sources(earlier):
    prior = population_prior(earlier)
    config = LearnerConfig(box=ParameterBox.from_bounds(TABLE_I), seed=9, prior=prior)
    learner = PreferenceLearner(config)
    drive(learner, 3)  # the first comparisons: the model exists
    far = torch.tensor([[0.0, 1.0, 1.0]], dtype=torch.float64)
    # away from the new participant's points the posterior mean is the prior's ...
    mean_far = float(posterior_at(learner.model.model, far)[0])
    prior_far = float(PopulationMean(prior)(far))
    zero_mean = PreferenceLearner(config.model_copy(update={"prior": None}))
    drive(zero_mean, 3)
    assert abs(mean_far - prior_far) < abs(float(posterior_at(zero_mean.model.model, far)[0])
                                           - prior_far)
    snapshot = learner.snapshot()
    assert snapshot.config.prior.sources == ["P01", "P02"]
    restored = PreferenceLearner.restore(snapshot)
    assert restored.suggest().theta == learner.suggest().theta


def test_comparisons_override_a_wrong_prior():
    """A prior that points at the opposite corner loses to the participant's own comparisons."""
    box = ParameterBox.unit_cube(2)
    wrong = PreferenceLearner(LearnerConfig(box=box, seed=0))
    for i, (w, l_) in enumerate([((1.0, 1.0), (0.0, 0.0)), ((0.9, 0.9), (0.2, 0.1))]):
        ids = (f"{i}w", f"{i}l")
        wrong.observe_many([Interaction(interaction_id=ids[0], theta={"x1": w[0], "x2": w[1]}),
                            Interaction(interaction_id=ids[1], theta={"x1": l_[0], "x2": l_[1]})],
                           [_beats(*ids)])
    prior = population_prior({"wrong": wrong.snapshot()}, weight=1.0)
    learner = PreferenceLearner(LearnerConfig(box=box, seed=0, prior=prior))
    points = [(0.1 * k, 0.1 * k) for k in range(10)]
    learner.observe_many([Interaction(interaction_id=str(k), theta={"x1": a, "x2": b})
                          for k, (a, b) in enumerate(points)],
                         [_beats(str(k), str(j)) for k in range(4) for j in range(k + 1, 10)
                          if j != k])
    assert learner.best().theta["x1"] < 0.35  # the participant's own best region, not the prior's


def _liking(box, winner, losers, seed=0):
    """An earlier participant who preferred ``winner`` to every point in ``losers``."""
    learner = PreferenceLearner(LearnerConfig(box=box, seed=seed))
    points = [winner, *losers]
    learner.observe_many([Interaction(interaction_id=str(k), theta={"x1": a, "x2": b})
                          for k, (a, b) in enumerate(points)],
                         [_beats("0", str(k)) for k in range(1, len(points))])
    return learner


def test_with_a_prior_the_first_handover_is_the_earlier_participants_best():
    """Interaction 1 is the earlier point where the pooled mean peaks (computed here from the
    pooled mean, not taken from the learner); with one earlier participant there is no other
    favourite to show, so the rest of the initial batch stays Sobol."""
    box = ParameterBox.unit_cube(2)
    earlier = PreferenceLearner(LearnerConfig(box=box, seed=0))
    corners = [(1.0, 1.0), (0.0, 0.0), (0.7, 0.6), (0.2, 0.1)]
    earlier.observe_many([Interaction(interaction_id=str(k), theta={"x1": a, "x2": b})
                          for k, (a, b) in enumerate(corners)],
                         [_beats("0", "1"), _beats("0", "3"), _beats("2", "1"), _beats("0", "2")])
    prior = population_prior({"P01": earlier.snapshot()})
    pooled = PopulationMean(prior)(torch.tensor(corners, dtype=torch.float64))
    expected = corners[int(torch.argmax(pooled))]
    assert expected == (1.0, 1.0)  # the point that won every comparison
    with_prior = PreferenceLearner(LearnerConfig(box=box, seed=3, prior=prior))
    without = PreferenceLearner(LearnerConfig(box=box, seed=3))
    first = with_prior.suggest().theta
    assert (first["x1"], first["x2"]) == pytest.approx(expected)
    assert without.suggest().theta != first
    for learner in (with_prior, without):
        learner.observe(Interaction(interaction_id="1", theta=learner.suggest().theta))
    assert with_prior.suggest().theta == without.suggest().theta  # Sobol point 2 for both


def test_the_initial_batch_shows_the_earlier_participants_distinct_favourites():
    """Four earlier participants, two of whom liked nearly the same handover (0.11 apart): the
    initial batch is the pooled best, then the other favourites farthest first, but not the one
    within DISTINCT_FAVOURITES of a shown one; Sobol points fill the rest. Each favourite is
    checked here from that participant's own posterior mean."""
    box = ParameterBox.unit_cube(2)
    losers = [(0.5, 0.5), (0.3, 0.2), (0.6, 0.1), (0.1, 0.6)]
    likes = {"P01": (0.9, 0.9), "P02": (0.1, 0.9), "P03": (0.85, 0.8), "P04": (0.5, 0.1)}
    earlier = {who: _liking(box, best, losers, seed=k)
               for k, (who, best) in enumerate(likes.items())}
    for who, learner in earlier.items():
        X = learner.model.model.datapoints
        own_best = X[int(torch.argmax(posterior_at(learner.model.model, X)[0]))].tolist()
        assert own_best == pytest.approx(likes[who])
    assert np.hypot(0.9 - 0.85, 0.9 - 0.8) < DISTINCT_FAVOURITES < np.hypot(0.5 - 0.1, 0.1 - 0.9)
    prior = population_prior({who: learner.snapshot() for who, learner in earlier.items()})
    pooled = PopulationMean(prior)(torch.tensor(list(likes.values()), dtype=torch.float64))
    pooled_best = list(likes.values())[int(torch.argmax(pooled))]
    assert pooled_best in (likes["P01"], likes["P03"])  # two of four liked that corner
    learner = PreferenceLearner(LearnerConfig(box=box, seed=3, prior=prior))
    shown = []
    for k in range(5):
        theta = learner.suggest().theta
        shown.append((theta["x1"], theta["x2"]))
        learner.observe(Interaction(interaction_id=str(k), theta=theta))
    # from either corner favourite, P04 is the farthest (> 0.76), then P02 (≥ 0.75 from both)
    assert shown[:3] == [pytest.approx(b) for b in (pooled_best, likes["P04"], likes["P02"])]
    assert shown[3:] == [(theta["x1"], theta["x2"]) for theta in _sobol(box, 3, [3, 4])]


def _sobol(box, seed, indices):
    """The Sobol points a learner without a prior shows in these initial slots."""
    learner = PreferenceLearner(LearnerConfig(box=box, seed=seed))
    shown = []
    for k in range(max(indices) + 1):
        theta = learner.suggest().theta
        if k in indices:
            shown.append(theta)
        learner.observe(Interaction(interaction_id=str(k), theta=theta))
    return shown


def _beats(winner, loser):
    from app.learning.models import Comparison

    return Comparison(winner=winner, loser=loser)


def test_no_model_or_mixed_boxes_is_a_clear_error(earlier):
    empty = PreferenceLearner(LearnerConfig(box=ParameterBox.from_bounds(TABLE_I))).snapshot()
    with pytest.raises(LearningError, match="none has a fitted preference model"):
        population_prior({"P09": empty})
    other = PreferenceLearner(LearnerConfig(box=ParameterBox.unit_cube(3))).snapshot()
    with pytest.raises(LearningError, match="different parameter boxes"):
        population_prior({**earlier, "X": other})


def test_population_targets_spread_around_a_shared_optimum():
    near = np.array([participant_target(3, 0, 4, i, 0.05) for i in range(40)])
    uniform = np.array([participant_target(3, 0, 4, i, None) for i in range(40)])
    assert near.std(0).max() < 0.08 < uniform.std(0).min()
    assert (participant_target(3, 0, 4, 1, 0.05) == near[1]).all()  # seeded
    other_population = np.array([participant_target(3, 0, 5, i, 0.05) for i in range(40)])
    assert np.abs(near.mean(0) - other_population.mean(0)).max() > 0.05
