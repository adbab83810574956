"""The likelihood that knows eq. (16): a comparison between batch positions i and j is
√((i² + j²)/2) times as noisy as one between two first positions."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from app.learning.comparison_noise import BatchPositionProbit, relative_noise
from app.learning.config import LearnerConfig, ModelConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox
from app.learning.preference_model import fit_model, posterior_at

N_POINTS = 4
PAIRS = [(w, l_) for w in range(N_POINTS) for l_ in range(N_POINTS) if w != l_]


def _log_likelihood(f: torch.Tensor, pairs: list[tuple[int, int]], scales: torch.Tensor):
    """Σ_k log Φ((f_w − f_l)/(√2 s_k)), written out."""
    normal = torch.distributions.Normal(0.0, 1.0)
    z = torch.stack([(f[w] - f[l_]) for w, l_ in pairs]) / (math.sqrt(2.0) * scales)
    return normal.cdf(z).log().sum()


@given(utilities=st.lists(st.floats(-2.0, 2.0), min_size=N_POINTS, max_size=N_POINTS),
       comparisons=st.lists(st.tuples(st.sampled_from(PAIRS), st.floats(1.0, 5.0)), min_size=1,
                            max_size=6))
def test_probability_gradient_and_hessian_are_those_of_the_scaled_probit(utilities, comparisons):
    """Slow: Hypothesis's default 100 examples, each checked against the log-likelihood's
    gradient and Hessian computed by torch.func."""
    f = torch.tensor(utilities, dtype=torch.float64)
    pairs = [pair for pair, _ in comparisons]
    scales = torch.tensor([s for _, s in comparisons], dtype=torch.float64)
    D = torch.zeros(len(pairs), N_POINTS, dtype=torch.float64)
    for k, (w, l_) in enumerate(pairs):
        D[k, w], D[k, l_] = 1.0, -1.0
    likelihood = BatchPositionProbit(scales)
    expected_p = torch.distributions.Normal(0.0, 1.0).cdf(
        (f[[w for w, _ in pairs]] - f[[l_ for _, l_ in pairs]]) / (math.sqrt(2.0) * scales))
    assert likelihood.p(f, D) == pytest.approx(expected_p.tolist(), rel=1e-9)
    gradient = torch.func.grad(lambda x: _log_likelihood(x, pairs, scales))(f)
    hessian = torch.func.hessian(lambda x: _log_likelihood(x, pairs, scales))(f)
    assert likelihood.negative_log_gradient_sum(f, D) == pytest.approx((-gradient).tolist(),
                                                                       abs=1e-9)
    assert likelihood.negative_log_hessian_sum(f, D).flatten().tolist() == pytest.approx(
        (-hessian).flatten().tolist(), abs=1e-9)


def test_scales_must_match_the_comparisons():
    with pytest.raises(ValueError, match="positive"):
        BatchPositionProbit(torch.tensor([1.0, 0.0]))
    likelihood = BatchPositionProbit(torch.tensor([1.0, 2.0]))
    with pytest.raises(ValueError, match="D has 1 comparisons but 2 scales"):
        likelihood.p(torch.zeros(2), torch.tensor([[1.0, -1.0]]))


def _contradicted(batch_position_noise: bool) -> PreferenceLearner:
    """A ≻ B said at batch positions 1 and 2, B ≻ A at positions 4 and 5; C (position 3) loses to
    both."""
    box = ParameterBox.unit_cube(2)
    learner = PreferenceLearner(LearnerConfig(
        box=box, seed=0, model=ModelConfig(batch_position_noise=batch_position_noise)))
    at = {"A": (0.2, 0.2), "B": (0.8, 0.8), "C": (0.2, 0.9)}
    shown = ["A", "B", "C", "B", "A"]  # the initial batch: positions 1 … 5
    learner.observe_many(
        [Interaction(interaction_id=f"{name}{j}", theta=dict(zip(box.names, at[name], strict=True)))
         for j, name in enumerate(shown, start=1)],
        [Comparison(winner="A1", loser="B2"), Comparison(winner="A1", loser="C3"),
         Comparison(winner="B2", loser="C3"), Comparison(winner="B4", loser="A5")])
    return learner


def test_a_comparison_early_in_the_batch_outweighs_a_contradicting_late_one():
    weighted, equal = _contradicted(True), _contradicted(False)
    assert weighted.data.comparison_noise == pytest.approx(
        [relative_noise(1, 2), relative_noise(1, 3), relative_noise(2, 3), relative_noise(4, 5)])
    assert relative_noise(4, 5) == pytest.approx(math.sqrt(20.5))
    # the Laplace posterior at the kernel's initial hyperparameters (four contradicting comparisons
    # are too few to fit them: the output scale collapses to its floor either way)
    ab = torch.tensor([[0.2, 0.2], [0.8, 0.8]], dtype=torch.float64)
    (a, b), _ = posterior_at(fit_model(weighted.data, weighted.config.model, optimize=False), ab)
    (a_equal, b_equal), _ = posterior_at(fit_model(equal.data, equal.config.model, optimize=False),
                                         ab)
    assert float(a - b) > 0.1  # the early comparison wins
    assert abs(float(a_equal - b_equal)) < 0.25 * float(a - b)  # equal trust: they nearly cancel
    restored = PreferenceLearner.restore(weighted.snapshot())
    assert restored.data.comparison_noise == weighted.data.comparison_noise
