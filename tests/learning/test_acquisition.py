"""The acquisition and recommendation searches: their L-BFGS-B tolerance, how kernels are evaluated."""

from __future__ import annotations

import pytest
import torch
from botorch.acquisition import PosteriorMean
from botorch.acquisition.monte_carlo import qNoisyExpectedImprovement
from pydantic import ValidationError

from app.learning.acquisition import propose
from app.learning.config import AcquisitionName, LearnerConfig, ModelConfig, OptimizerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import ParameterBox, RecommendationName
from app.learning.recommendation import recommend

from .conftest import TABLE_I, drive


@pytest.fixture(scope="module")
def trained() -> PreferenceLearner:
    learner = PreferenceLearner(LearnerConfig(box=ParameterBox.from_bounds(TABLE_I), seed=5))
    drive(learner, 12)
    return learner


def _evaluations(monkeypatch, acquisition_class) -> list[int]:
    """Count the forward passes of BoTorch's ``acquisition_class`` (the search's cost)."""
    calls = [0]
    forward = acquisition_class.forward

    def counted(self, X):
        calls[0] += 1
        return forward(self, X)

    monkeypatch.setattr(acquisition_class, "forward", counted)
    return calls


def test_a_looser_tolerance_ends_the_acquisition_search_sooner_inside_the_box(trained,
                                                                               monkeypatch):
    """Slow: the module's learner is trained here (12 interactions of its schedule: model
    fits and qNEI searches), then two qNEI searches."""
    calls = _evaluations(monkeypatch, qNoisyExpectedImprovement)
    model = trained.model.model
    best_x = torch.tensor(trained.data.points[0], dtype=torch.float64)
    counts, picks = [], []
    for tolerance in (None, 1e-2):
        calls[0] = 0
        config = OptimizerConfig(num_restarts=2, raw_samples=64, mc_samples=64,
                                 tolerance=tolerance)
        picks.append(propose(AcquisitionName.QNEI, model, best_x, config, seed=11))
        counts.append(calls[0])
    assert counts[1] < counts[0], counts
    for pick in picks:
        assert ((pick >= 0.0) & (pick <= 1.0)).all()


def test_a_looser_tolerance_ends_the_recommendation_search_sooner(trained, monkeypatch):
    calls = _evaluations(monkeypatch, PosteriorMean)
    counts = []
    for tolerance in (None, 1e-2):
        calls[0] = 0
        config = OptimizerConfig(num_restarts=2, raw_samples=64, tolerance=tolerance)
        recommend(RecommendationName.POSTERIOR_MEAN, trained.model.model, trained.data, config,
                  seed=11)
        counts.append(calls[0])
    assert counts[1] < counts[0], counts


@pytest.mark.parametrize("tolerance", [0.0, -1e-3, 1.0])
def test_a_tolerance_outside_its_range_is_refused_naming_the_field(tolerance):
    with pytest.raises(ValidationError, match="tolerance") as error:
        OptimizerConfig(tolerance=tolerance)
    assert "greater than 0" in str(error.value) or "less than 1" in str(error.value)


def _lazy_kernel_tensors(monkeypatch) -> list[int]:
    """Count GPyTorch's lazy kernel tensors as they are built."""
    from gpytorch.lazy import LazyEvaluatedKernelTensor

    built = [0]
    init = LazyEvaluatedKernelTensor.__init__

    def counted(self, *args, **kwargs):
        built[0] += 1
        init(self, *args, **kwargs)

    monkeypatch.setattr(LazyEvaluatedKernelTensor, "__init__", counted)
    return built


def test_kernels_evaluated_directly_give_the_lazy_tensors_numbers(monkeypatch):
    """Slow (28-41 s in a loaded full run): the learner's schedule of 9 interactions is run twice
    in the test process, once with GPyTorch's lazy kernel tensors and once without, each with its
    fits and acquisitions."""
    built = _lazy_kernel_tensors(monkeypatch)
    runs = {}
    for lazy in (True, False):
        built[0] = 0
        learner = PreferenceLearner(LearnerConfig(
            box=ParameterBox.from_bounds(TABLE_I), seed=9,
            model=ModelConfig(lazy_kernels=lazy),
            optimizer=OptimizerConfig(num_restarts=2, raw_samples=32, mc_samples=32)))
        shown = drive(learner, 9)
        runs[lazy] = (shown, learner.best(), built[0])
    assert runs[True][0] == runs[False][0]  # every suggestion, to the last bit
    assert runs[True][1] == runs[False][1]
    assert runs[True][2] > 0
    assert runs[False][2] == 0, "a kernel was still evaluated lazily in the learner's own work"
