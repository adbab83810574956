"""θ* recommendation strategies: what each returns on the same posterior, and where it is recorded."""

from __future__ import annotations

import pytest
import torch

from app.learning.config import LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox, RecommendationName
from app.learning.preference_model import posterior_at

from .conftest import TABLE_I, drive


@pytest.fixture(scope="module")
def trained():
    learner = PreferenceLearner(LearnerConfig(box=ParameterBox.from_bounds(TABLE_I), seed=3))
    drive(learner, 12)
    return learner


def _unit(learner, theta):
    return torch.tensor([learner.config.box.to_unit(theta)], dtype=torch.float64)


def test_in_sample_strategies_return_observed_points_and_the_box_search_a_higher_mean(trained):
    """Slow: the module's learner is trained here (12 interactions of its schedule: model
    fits and qNEI searches), then a search of the box for the posterior mean's maximum."""
    model = trained.model.model
    X, _ = trained.data.tensors()
    mean, std = posterior_at(model, X)
    in_sample = trained.best(RecommendationName.IN_SAMPLE_MEAN)
    lcb = trained.best(RecommendationName.IN_SAMPLE_LCB)
    box = trained.best(RecommendationName.POSTERIOR_MEAN)
    assert in_sample.strategy is RecommendationName.IN_SAMPLE_MEAN and in_sample.interaction_ids
    assert in_sample.utility_mean == pytest.approx(float(mean.max()))
    # LCB: the observed point maximising mean − β·std (β = 1), by direct computation
    index = int((mean - std).argmax())
    assert trained.config.box.to_unit(lcb.theta) == pytest.approx(trained.data.points[index])
    assert lcb.interaction_ids == trained.data.interactions_at(index)
    # the box maximiser is never worse in posterior mean than the in-sample argmax
    assert box.utility_mean >= in_sample.utility_mean - 1e-9
    assert float(posterior_at(model, _unit(trained, box.theta))[0]) == pytest.approx(
        box.utility_mean, rel=1e-6)
    if box.interaction_ids == ():
        assert box.utility_mean > in_sample.utility_mean


def test_the_configured_strategy_is_the_default_of_best_and_is_stored(trained):
    config = trained.config.model_copy(update={"recommendation": RecommendationName.IN_SAMPLE_LCB})
    learner = PreferenceLearner.restore(trained.snapshot().model_copy(update={"config": config}))
    assert learner.best().strategy is RecommendationName.IN_SAMPLE_LCB
    assert learner.best() == trained.best(RecommendationName.IN_SAMPLE_LCB)
    assert learner.snapshot().config.recommendation is RecommendationName.IN_SAMPLE_LCB


def test_a_batch_still_opens_with_the_observed_incumbent_whatever_the_strategy():
    config = LearnerConfig(box=ParameterBox.from_bounds(TABLE_I), seed=5,
                           recommendation=RecommendationName.POSTERIOR_MEAN)
    learner = PreferenceLearner(config)
    drive(learner, config.schedule.n_initial)
    suggestion = learner.suggest()
    assert suggestion.slot.kind.value == "best"
    assert suggestion.theta == learner.best(RecommendationName.IN_SAMPLE_MEAN).theta


def test_before_any_comparison_theta_star_is_the_first_point_without_a_strategy():
    learner = PreferenceLearner(LearnerConfig(box=ParameterBox.from_bounds(TABLE_I)))
    theta = learner.suggest().theta
    learner.observe(Interaction(interaction_id="1", theta=theta), [])
    best = learner.best()
    assert best.theta == theta and best.strategy is None and best.utility_mean is None
    with pytest.raises(ValueError, match="not known"):
        learner.observe(Interaction(interaction_id="2", theta=theta),
                        [Comparison(winner="2", loser="9")])
