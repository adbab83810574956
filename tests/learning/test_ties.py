"""Ties as information (``ties = "model"``): an "equal" placement enters the likelihood as two
half-weighted opposite comparisons (Davidson's tie model in probit form, app.learning.ties)."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from app.learning.comparison_noise import BatchPositionProbit
from app.learning.config import LearnerConfig, ModelConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox, Placement, TieHandling
from app.learning.preference_model import posterior_at
from app.learning.scale import comparisons_for_newest

N_POINTS = 3
PAIRS = [(w, l_) for w in range(N_POINTS) for l_ in range(N_POINTS) if w != l_]


@given(utilities=st.lists(st.floats(-2.0, 2.0), min_size=N_POINTS, max_size=N_POINTS),
       rows=st.lists(st.tuples(st.sampled_from(PAIRS), st.sampled_from([0.5, 1.0])),
                     min_size=1, max_size=5))
def test_weighted_probit_is_the_weighted_sum_of_log_probits(utilities, rows):
    """log L = Σ_k w_k log Φ(z_k): probability, gradient and Hessian (those the Laplace
    approximation of eq. (13) uses) against autograd of the formula written out."""
    f = torch.tensor(utilities, dtype=torch.float64)
    pairs = [pair for pair, _ in rows]
    weights = torch.tensor([w for _, w in rows], dtype=torch.float64)
    D = torch.zeros(len(pairs), N_POINTS, dtype=torch.float64)
    for k, (w, l_) in enumerate(pairs):
        D[k, w], D[k, l_] = 1.0, -1.0

    def log_likelihood(x: torch.Tensor) -> torch.Tensor:
        z = torch.stack([x[w] - x[l_] for w, l_ in pairs]) / math.sqrt(2.0)
        return (weights * torch.distributions.Normal(0.0, 1.0).cdf(z).log()).sum()

    likelihood = BatchPositionProbit(torch.ones(len(pairs), dtype=torch.float64), weights)
    assert likelihood.p(f, D).log().sum().item() == pytest.approx(log_likelihood(f).item(),
                                                                  abs=1e-9)
    gradient = torch.func.grad(log_likelihood)(f)
    hessian = torch.func.hessian(log_likelihood)(f)
    assert likelihood.negative_log_gradient_sum(f, D).tolist() == pytest.approx(
        (-gradient).tolist(), abs=1e-9)
    assert likelihood.negative_log_hessian_sum(f, D).flatten().tolist() == pytest.approx(
        (-hessian).flatten().tolist(), abs=1e-9)


def test_the_scale_rule_names_ties_only_when_asked():
    """An "equal" placement makes no comparison (the paper); asked, it makes a tie."""
    batch = [Placement(interaction_id="1", position=0.3), Placement(interaction_id="2", position=0.7),
             Placement(interaction_id="3", equal_to="1")]
    assert comparisons_for_newest(batch) == [Comparison(winner="2", loser="3")]
    assert comparisons_for_newest(batch, ties=True) == [
        Comparison(winner="3", loser="1", tie=True), Comparison(winner="2", loser="3")]


BOX = ParameterBox.unit_cube(2)
A, B, C = {"x1": 0.2, "x2": 0.2}, {"x1": 0.8, "x2": 0.3}, {"x1": 0.5, "x2": 0.9}


def _learner(ties: TieHandling) -> PreferenceLearner:
    """A ≻ B once, C worst; then A and B shown again and placed "equal" twice."""
    learner = PreferenceLearner(LearnerConfig(box=BOX, seed=0, model=ModelConfig(ties=ties)))
    shown = [("1", A), ("2", B), ("3", C), ("4", A), ("5", B), ("6", A), ("7", B)]
    learner.observe_many([Interaction(interaction_id=i, theta=t) for i, t in shown], [
        Comparison(winner="1", loser="2"), Comparison(winner="1", loser="3"),
        Comparison(winner="2", loser="3"), Comparison(winner="5", loser="4", tie=True),
        Comparison(winner="7", loser="6", tie=True)])
    return learner


def test_modelled_ties_enter_the_likelihoods_data_as_half_weighted_opposite_pairs():
    dropped, modelled = _learner(TieHandling.DROP), _learner(TieHandling.MODEL)
    assert dropped.data.comparisons == [(0, 1), (0, 2), (1, 2)]
    assert dropped.data.n_ties == 0 and set(dropped.data.comparison_weight) == {1.0}
    assert modelled.data.comparisons == [(0, 1), (0, 2), (1, 2), (1, 0), (0, 1), (1, 0), (0, 1)]
    assert modelled.data.comparison_weight == [1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5]
    assert modelled.data.n_ties == 2 and modelled.last_fit.n_comparisons == 7


def test_a_modelled_tie_pulls_the_two_utilities_together():
    """"Equal" twice after A ≻ B once: the posterior gap u(A) − u(B) shrinks when the ties are
    information, and stays what A ≻ B alone says when they are dropped."""
    gaps = {}
    for ties in TieHandling:
        learner = _learner(ties)
        mean, _ = posterior_at(learner.model.model, torch.tensor(
            [BOX.to_unit(A), BOX.to_unit(B)], dtype=torch.float64))
        gaps[ties] = float(mean[0] - mean[1])
    assert gaps[TieHandling.DROP] > 0 and gaps[TieHandling.MODEL] > 0
    assert gaps[TieHandling.MODEL] < 0.8 * gaps[TieHandling.DROP], gaps


def test_a_snapshot_keeps_the_ties_and_restores_them():
    learner = _learner(TieHandling.MODEL)
    restored = PreferenceLearner.restore(learner.snapshot())
    assert restored.data.comparisons == learner.data.comparisons
    assert restored.data.comparison_weight == learner.data.comparison_weight
