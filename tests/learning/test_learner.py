"""The learner: index reuse, dropped self-comparisons, failed fits, seeds, snapshots."""

from __future__ import annotations

import warnings

import pytest
import torch
from botorch.exceptions import ModelFittingError
from botorch.exceptions.warnings import OptimizationWarning
from botorch.fit import fit_gpytorch_mll
from botorch.optim.fit import fit_gpytorch_mll_scipy

from app.learning import preference_model
from app.learning.acquisition import propose
from app.learning.errors import UnknownInteractionError
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, RecommendationName, SlotKind
from app.learning.rng import derive_seed

from .conftest import drive


def test_theta_star_shown_again_reuses_its_datapoint_index(make_learner):
    learner = make_learner()
    drive(learner, 4)  # the initial batch
    suggestion = learner.suggest()
    assert suggestion.slot.kind is SlotKind.BEST
    best = learner.best(RecommendationName.IN_SAMPLE_MEAN)  # the batch-opening θ*
    assert suggestion.theta == best.theta == learner.incumbent()
    n_points = len(learner.data.points)
    learner.observe(Interaction(interaction_id="5", theta=suggestion.theta))
    assert len(learner.data.points) == n_points
    index = learner.data.index_of("5")
    assert learner.data.index_of(best.interaction_ids[0]) == index
    assert learner.data.interactions_at(index) == (*best.interaction_ids, "5")


def test_a_near_twin_is_merged_and_its_self_comparison_dropped(make_learner):
    learner = make_learner()
    drive(learner, 4)
    best = learner.best(RecommendationName.IN_SAMPLE_MEAN)  # an observed point
    twin = {**best.theta, "a": best.theta["a"] + 1e-4 * 9.0}  # 1e-4 of the width: below tolerance
    m = len(learner.data.comparisons)
    report = learner.observe(Interaction(interaction_id="5", theta=twin),
                             [Comparison(winner="5", loser=best.interaction_ids[0])])
    assert not report.refitted
    assert len(learner.data.comparisons) == m
    assert learner.data.index_of("5") == learner.data.index_of(best.interaction_ids[0])


def test_comparisons_with_unknown_interactions_are_rejected_without_side_effects(make_learner):
    learner = make_learner()
    drive(learner, 2)
    before = (len(learner.data.points), len(learner.data.comparisons), learner.n_interactions)
    with pytest.raises(UnknownInteractionError, match="interaction_id = '99'"):
        learner.observe(Interaction(interaction_id="3", theta=learner.suggest().theta),
                        [Comparison(winner="3", loser="99")])
    assert (len(learner.data.points), len(learner.data.comparisons),
            learner.n_interactions) == before


def _always_warning_optimizer(mll, closure=None, **kwargs):
    """A real scipy fit that also reports an optimisation warning, so BoTorch retries and fails."""
    result = fit_gpytorch_mll_scipy(mll, closure=closure, **kwargs)
    warnings.warn("forced by the test", OptimizationWarning, stacklevel=1)
    return result


def test_a_failed_fit_keeps_the_previous_model_and_is_reported(make_learner, monkeypatch):
    """Slow: five interactions of the learner's schedule (model fits and qNEI searches), then a fit
    that BoTorch tries again and again before it fails, each try a whole scipy fit."""
    learner = make_learner()
    drive(learner, 5)  # the initial batch and θ* opening batch 1
    previous = learner.model.model
    assert previous is not None

    def failing_fit(mll, **kwargs):
        return fit_gpytorch_mll(mll, **{**kwargs, "optimizer": _always_warning_optimizer})

    monkeypatch.setattr(preference_model, "fit_gpytorch_mll", failing_fit)
    suggestion = learner.suggest()
    assert suggestion.slot.kind is SlotKind.QUERY
    report = learner.observe(Interaction(interaction_id="6", theta=suggestion.theta),
                             [Comparison(winner="6", loser="5")])
    assert report.fit_failed and report.refitted
    assert "ModelFittingError" in report.message
    assert learner.model.model is previous
    # the session goes on: θ* over all points (the new one included) and the next θ
    assert learner.best() is not None
    nxt = learner.suggest()
    assert nxt.theta is not None and nxt.fit.fit_failed


def test_the_fit_failure_is_botorchs_own():
    with pytest.raises(ModelFittingError):
        from botorch.models.pairwise_gp import PairwiseGP, PairwiseLaplaceMarginalLogLikelihood

        X = torch.rand(4, 3, dtype=torch.float64)
        model = PairwiseGP(X, torch.tensor([[0, 1], [2, 3]]))
        mll = PairwiseLaplaceMarginalLogLikelihood(model.likelihood, model)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OptimizationWarning)
            fit_gpytorch_mll(mll, optimizer=_always_warning_optimizer, max_attempts=2)


@pytest.mark.parametrize("acquisition", ["qnei", "qlognei", "eubo", "sobol"])
def test_same_seed_same_suggestions_and_points_stay_in_the_box(make_learner, acquisition):
    """Three learners of 7 interactions each (two of one seed, one of another), each fitting and
    optimising its acquisition: up to ~21 s on a loaded machine (the qNEI case beside a busy core)."""
    first = drive(make_learner(acquisition, seed=5), 7)
    second = drive(make_learner(acquisition, seed=5), 7)
    assert first == second
    box = make_learner().config.box
    for theta in first:
        box.to_unit(theta)  # raises outside the box
    other = drive(make_learner(acquisition, seed=6), 7)
    assert other != first


def test_qnei_construction_warning_does_not_reach_the_caller(make_learner):
    learner = make_learner("qnei")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        drive(learner, 6)
    assert not [w for w in caught if "qLogNoisyExpectedImprovement" in str(w.message)]


def test_snapshot_round_trip_restores_the_same_best_point(make_learner):
    learner = make_learner()
    drive(learner, 6)
    snapshot = learner.snapshot()
    restored = PreferenceLearner.restore(type(snapshot).model_validate_json(
        snapshot.model_dump_json()))
    assert restored.n_interactions == learner.n_interactions
    assert restored.data.comparisons == learner.data.comparisons
    assert restored.best().theta == learner.best().theta
    assert restored.next_slot() == learner.next_slot()


def lazy_learner(make_learner, acquisition: str) -> PreferenceLearner:
    config = make_learner(acquisition).config
    return PreferenceLearner(config.model_copy(update={"model": config.model.model_copy(
        update={"lazy_fit": True})}))


def test_lazy_fit_refits_before_a_sobol_query_too(make_learner):
    learner = lazy_learner(make_learner, "sobol")
    drive(learner, 6)
    assert learner.model.needs_fit(learner.data)
    suggestion = learner.suggest()
    assert suggestion.slot.kind is SlotKind.QUERY and suggestion.fit.hyperparameters_fitted
    assert not learner.model.needs_fit(learner.data)


def test_lazy_fit_queries_use_the_model_fitted_just_before(make_learner):
    learner = lazy_learner(make_learner, "qnei")
    lazy = learner.config
    drive(learner, 6)  # initial batch, θ*, one query: its comparisons are not fitted yet
    assert learner.model.needs_fit(learner.data)
    suggestion = learner.suggest()
    assert suggestion.slot.kind is SlotKind.QUERY and suggestion.fit.hyperparameters_fitted
    assert not learner.model.needs_fit(learner.data)
    index, _ = learner.model.best(learner.data)
    expected = propose(lazy.acquisition, learner.model.model,
                       torch.tensor(learner.data.points[index], dtype=torch.float64),
                       lazy.optimizer, derive_seed(lazy.seed, suggestion.slot.index, 2))
    assert learner.config.box.to_unit(suggestion.theta) == pytest.approx(expected.tolist())
