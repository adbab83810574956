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
from app.learning.simulation import StudyCondition, simulate_learner

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
    interactions, comparisons = hint_observations("7", hinted_theta(
        {"a": 4.0, "delta": 0.0, "k": 3.0}, BOX, HintDirection(parameter="k", sign=-1), 0.1))
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
        hint_points, hint_comparisons = hint_observations(str(number), hinted_theta(
            theta, BOX, HintDirection(parameter="k", sign=1), 0.3))
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


# The simulated participant's hints (app.learning.simulation, coactive=True)

COACTIVE = StudyCondition(q=3, noise=0.3, n_unique=7, n_initial=3, coactive=True)
FAR_TARGET = np.array([0.5, 1.0, 0.0])  # up along x2 and down along x3 feel better from most θ


def test_a_coactive_participant_hints_and_the_learner_holds_them_as_points_never_shown():
    result, learner = simulate_learner(COACTIVE, FAR_TARGET, 11, 12, 13)
    snapshot = learner.snapshot()
    shown = {i.interaction_id: i.theta for i in snapshot.interactions if i.shown}
    hinted = [i for i in snapshot.interactions if not i.shown]
    assert result.hints == len(hinted) > 0
    assert len(shown) == learner.n_interactions == COACTIVE.schedule.n_interactions
    box = learner.config.box
    for point in hinted:
        handover = point.interaction_id.removeprefix("hint-")
        assert Comparison(winner=point.interaction_id, loser=handover) in snapshot.comparisons
        moved = {n for n in box.names if point.theta[n] != pytest.approx(shown[handover][n])}
        assert len(moved) == 1 and moved <= {"x2", "x3"}  # δ and k analogues; never x1 (a)
        (name,) = moved
        assert abs(point.theta[name] - shown[handover][name]) <= COACTIVE.hint_step + 1e-12
    # θ* is recorded in the unit cube: its distance to the target is the final inference distance
    assert float(np.linalg.norm(np.array(result.theta_star) - FAR_TARGET)) == pytest.approx(
        result.distances[-1])


def test_hints_draw_their_own_noise_so_the_placements_are_those_of_the_arm_without_hints():
    """Paired arms: the hints' noise comes from its own generator, so the first batch (the same
    Sobol points) is placed exactly as by the same participant without hints."""
    _, hinting = simulate_learner(COACTIVE, FAR_TARGET, 11, 12, 13)
    _, plain = simulate_learner(COACTIVE.model_copy(update={"coactive": False}), FAR_TARGET,
                                11, 12, 13)
    first_batch = {str(n) for n in range(1, COACTIVE.n_initial + 1)}

    def placed(learner: PreferenceLearner) -> list[Comparison]:
        return [c for c in learner.snapshot().comparisons
                if {c.winner, c.loser} <= first_batch]

    assert any(i.interaction_id.removeprefix("hint-") in first_batch
               for i in hinting.snapshot().interactions if not i.shown)  # hints were drawn there
    assert placed(hinting) == placed(plain) and placed(plain)
