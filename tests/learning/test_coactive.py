"""Coactive hints (app.learning.coactive): a hint about the handover run with θ is one comparison
θ' ≻ θ, θ' = θ moved along the named parameter, never shown, never θ* in the sample."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from app.learning.coactive import (
    HintDirection,
    felt_hint,
    hint_id,
    hint_observations,
    hinted_theta,
)
from app.learning.config import LearnerConfig
from app.learning.errors import ParameterBoxError
from app.learning.learner import PreferenceLearner
from app.learning.models import Comparison, Interaction, ParameterBox, RecommendationName
from app.learning.planner import BatchSchedule
from app.learning.preference_model import posterior_at

BOX = ParameterBox.from_bounds({"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)})


@given(delta=st.floats(-1.0, 1.0), sign=st.sampled_from([-1, 1]), step=st.floats(0.01, 1.0))
def test_the_hinted_theta_moves_one_parameter_by_its_share_of_the_range_within_the_box(
        delta, sign, step):
    theta = {"a": 4.0, "delta": delta, "k": 3.0}
    moved = hinted_theta(theta, BOX, HintDirection(parameter="delta", sign=sign), step)
    expected = min(max(delta + sign * step * 2.0, -1.0), 1.0)
    if abs(expected - delta) < 2e-3:
        assert moved is None  # at the edge the hint points past: nothing to compare
    else:
        assert moved == {"a": 4.0, "delta": pytest.approx(expected), "k": 3.0}


def test_a_hint_with_an_unknown_parameter_or_step_names_the_field_and_range():
    with pytest.raises(ParameterBoxError, match=r"hint parameter = 'x' is not one of"):
        hinted_theta({"a": 4.0, "delta": 0.0, "k": 3.0}, BOX, HintDirection(parameter="x", sign=1),
                     0.2)
    with pytest.raises(ParameterBoxError, match=r"hint step = 0.0 is outside .*\(0, 1\]"):
        hinted_theta({"a": 4.0, "delta": 0.0, "k": 3.0}, BOX,
                     HintDirection(parameter="k", sign=1), 0.0)


def test_a_hint_is_a_point_not_shown_preferred_to_the_handover():
    interactions, comparisons = hint_observations(
        "7", {"a": 4.0, "delta": 0.0, "k": 3.0}, BOX, HintDirection(parameter="k", sign=-1), 0.1)
    (point,) = interactions
    assert (point.interaction_id, point.shown) == ("hint-7", False)
    assert point.theta == {"a": 4.0, "delta": 0.0, "k": pytest.approx(3.0 - 0.1 * 14.99)}
    assert comparisons == [Comparison(winner=hint_id("7"), loser="7")]


def _learner() -> PreferenceLearner:
    return PreferenceLearner(LearnerConfig(box=BOX, seed=3,
                                           schedule=BatchSchedule(n_initial=3, q=3, n_unique=6)))


def _observe_with_hint(learner: PreferenceLearner) -> None:
    for number in range(1, 4):
        theta = learner.suggest().theta
        assert theta is not None
        comparisons = [Comparison(winner=str(number), loser=str(earlier))
                       for earlier in range(1, number)]
        hint_points, hint_comparisons = hint_observations(
            str(number), theta, BOX, HintDirection(parameter="k", sign=1), 0.3)
        learner.observe_many([Interaction(interaction_id=str(number), theta=theta), *hint_points],
                             comparisons + hint_comparisons)


def test_hinted_points_shape_the_posterior_but_not_the_schedule_nor_the_in_sample_best():
    learner = _learner()
    _observe_with_hint(learner)
    assert learner.n_interactions == 3
    assert learner.next_slot().index == 3  # the hints took no slot of the schedule
    assert sum(learner.data.shown) == 3 and len(learner.data.points) == 6
    # every hinted point beats its handover, so the largest posterior mean is at a hinted point
    model = learner.model.model
    assert model is not None
    X, _ = learner.data.tensors()
    mean, _ = posterior_at(model, X)
    assert not learner.data.shown[int(mean.argmax())]
    # …yet θ* opening the next batch and θ* in the sample are handovers that were run
    incumbent = learner.incumbent()
    assert incumbent is not None
    assert incumbent in [i.theta for i in learner.snapshot().interactions if i.shown]
    best = learner.best(RecommendationName.IN_SAMPLE_MEAN)
    assert best is not None and best.interaction_ids and "hint" not in best.interaction_ids[0]


def test_a_restored_learner_with_hints_suggests_what_the_live_one_does():
    live = _learner()
    _observe_with_hint(live)
    restored = PreferenceLearner.restore(live.snapshot())
    assert restored.n_interactions == live.n_interactions
    assert restored.suggest().theta == live.suggest().theta


def test_the_simulated_hint_is_the_direction_felt_best_or_none_below_the_threshold():
    up, down = HintDirection(parameter="k", sign=1), HintDirection(parameter="k", sign=-1)
    rng = np.random.default_rng(0)
    assert felt_hint({up: 0.3, down: -0.3}, 0.01, 0.05, rng) == up
    assert felt_hint({up: 0.01, down: -0.01}, 0.001, 0.05, rng) is None
