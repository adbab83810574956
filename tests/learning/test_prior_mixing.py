"""Matched mixing of a prior from earlier participants: each earlier participant weighed by the
probability that the new participant compares like them (app.learning.prior), 'like nobody'
included; checked against the formula on posterior means computed by the earlier learners."""

from __future__ import annotations

import math

import pytest
import torch
from scipy.stats import norm

from app.learning.config import LearnerConfig
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox
from app.learning.population import PopulationMean, population_prior
from app.learning.preference_model import posterior_at
from app.learning.prior import PriorMixing

BOX = ParameterBox.unit_cube(2)
LOSERS = [(0.5, 0.5), (0.3, 0.2), (0.6, 0.1), (0.1, 0.6)]
LIKES = {"P01": (0.9, 0.9), "P02": (0.1, 0.9)}


def _observe(learner: PreferenceLearner, points, comparisons) -> None:
    learner.observe_many([Interaction(interaction_id=str(k), theta={"x1": a, "x2": b})
                          for k, (a, b) in enumerate(points)],
                         [Comparison(winner=str(w), loser=str(l_)) for w, l_ in comparisons])


@pytest.fixture(scope="module")
def earlier() -> dict[str, PreferenceLearner]:
    """Two earlier participants with opposite favourites, each preferred to every loser."""
    learners = {}
    for seed, (who, best) in enumerate(LIKES.items()):
        learner = PreferenceLearner(LearnerConfig(box=BOX, seed=seed))
        _observe(learner, [best, *LOSERS], [(0, k) for k in range(1, len(LOSERS) + 1)])
        learners[who] = learner
    return learners


def _prior(earlier, mixing=PriorMixing.MATCHED, weight=1.0):
    return population_prior({who: learner.snapshot() for who, learner in earlier.items()},
                            weight=weight, mixing=mixing)


# The new participant's handovers: the two favourites and points between them.
SHOWN = [(0.1, 0.9), (0.9, 0.9), (0.2, 0.8), (0.8, 0.8), (0.5, 0.9)]


def test_the_mixture_is_the_posterior_probability_of_comparing_like_each_earlier_participant(
        earlier):
    """π ∝ (½^m, Π_k Φ((m_p(r_k) − m_p(c_k))/√2) for p = 1, 2), m_p from each earlier learner's
    own posterior; the mean is w·Σ π_p m_p."""
    comparisons = [(0, 1), (2, 3), (0, 4), (2, 1)]  # the P02-like side wins
    X = torch.tensor(SHOWN, dtype=torch.float64)
    C = torch.tensor(comparisons)
    means = [posterior_at(learner.model.model, X)[0].numpy() for learner in earlier.values()]
    loglik = [math.log(0.5) * len(comparisons)] + [
        sum(norm.logcdf((m[r] - m[c]) / math.sqrt(2)) for r, c in comparisons) for m in means]
    expected = torch.softmax(torch.tensor(loglik), 0)[1:]
    mean = PopulationMean(_prior(earlier, weight=0.7)).matched_to(
        X, C, torch.ones(len(comparisons), dtype=torch.float64))
    assert mean.mixture.tolist() == pytest.approx(expected.tolist(), rel=1e-6)
    assert float(expected[1]) > 0.5 > float(expected[0])  # this participant compares like P02
    assert mean(X).tolist() == pytest.approx(
        (0.7 * (expected[0] * means[0] + expected[1] * means[1])).tolist(), rel=1e-6, abs=1e-9)


def test_noisier_comparisons_move_the_mixture_less(earlier):
    """With the batch-position noise of eq. (16) (s_k > 1) the same comparisons are weaker evidence."""
    X = torch.tensor(SHOWN, dtype=torch.float64)
    C = torch.tensor([(0, 1), (2, 3)])
    mean = PopulationMean(_prior(earlier))
    sure = mean.matched_to(X, C, torch.ones(2, dtype=torch.float64)).mixture
    unsure = mean.matched_to(X, C, torch.full((2,), 3.0, dtype=torch.float64)).mixture
    assert 0.5 < float(unsure[1]) < float(sure[1])


def test_a_participant_like_one_earlier_participant_gets_that_participants_prior(earlier):
    """After comparisons on the P02 side only, the learner's prior mean is P02's: at P02's
    favourite it is higher and at P01's lower than the pooled mean (P02 is the likelier
    hypothesis); the pooled learner keeps
    1/2 each, and restoring the matched learner gives the same mixture and suggestion."""
    comparisons = [(0, 1), (0, 2), (1, 2)]  # of SHOWN[0], SHOWN[2], SHOWN[4]: P02's side wins
    learners = {}
    for mixing in PriorMixing:
        learner = PreferenceLearner(LearnerConfig(box=BOX, seed=4, prior=_prior(earlier, mixing)))
        _observe(learner, [SHOWN[0], SHOWN[2], SHOWN[4]], comparisons)
        learners[mixing] = learner
    used = {m: learner.model.model.population_mean for m, learner in learners.items()}
    assert used[PriorMixing.POOLED].mixture.tolist() == [0.5, 0.5]
    assert float(used[PriorMixing.MATCHED].mixture[1]) > 0.5
    favourites = torch.tensor([LIKES["P01"], LIKES["P02"]], dtype=torch.float64)
    matched, pooled = used[PriorMixing.MATCHED](favourites), used[PriorMixing.POOLED](favourites)
    assert matched[1] > pooled[1] and matched[0] < pooled[0]
    restored = PreferenceLearner.restore(learners[PriorMixing.MATCHED].snapshot())
    assert restored.snapshot().config.prior.mixing is PriorMixing.MATCHED
    assert (restored.model.model.population_mean.mixture.tolist()
            == used[PriorMixing.MATCHED].mixture.tolist())
    assert restored.suggest().theta == learners[PriorMixing.MATCHED].suggest().theta


def test_a_participant_like_nobody_keeps_almost_no_prior(earlier):
    """Both earlier participants' favourites lose to a point both of them disliked: 'like
    nobody' takes the mixture, and the prior mean nearly vanishes."""
    X = torch.tensor([LOSERS[0], LIKES["P01"], LIKES["P02"]], dtype=torch.float64)
    C = torch.tensor([(0, 1), (0, 2), (0, 1), (0, 2)])
    mean = PopulationMean(_prior(earlier))
    matched = mean.matched_to(X, C, torch.ones(len(C), dtype=torch.float64))
    assert float(matched.mixture.sum()) < 0.05
    assert matched(X).abs().max() < 0.05 * mean(X).abs().max()


def test_before_any_comparison_matched_and_pooled_agree(earlier):
    X = torch.tensor(SHOWN, dtype=torch.float64)
    no_comparisons = torch.zeros((0, 2), dtype=torch.long)
    matched = PopulationMean(_prior(earlier)).matched_to(X, no_comparisons,
                                                         torch.ones(0, dtype=torch.float64))
    pooled = PopulationMean(_prior(earlier, PriorMixing.POOLED))
    assert matched(X).tolist() == pytest.approx(pooled(X).tolist())
