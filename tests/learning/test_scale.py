"""The refreshing relative scale → comparisons rule (Sect. III-C, Fig. 1)."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from app.learning.errors import ScaleError
from app.learning.models import Comparison, Placement
from app.learning.scale import comparisons_for_newest


def at(iid: str, position: float) -> Placement:
    return Placement(interaction_id=iid, position=position)


def test_fig1_example_after_interaction_4():
    # Fig. 1: on the scale 2 < 1 < 3; "4" is placed on marker "1" (equal), hence above 2, below 3.
    batch = [at("1", 0.5), at("2", 0.2), at("3", 0.8), Placement(interaction_id="4", equal_to="1")]
    assert comparisons_for_newest(batch) == [
        Comparison(winner="4", loser="2"),
        Comparison(winner="3", loser="4"),
    ]


def test_each_earlier_interaction_is_compared_with_the_newest_only():
    batch = [at("1", 0.5), at("2", 0.2), at("3", 0.8)]
    assert comparisons_for_newest(batch) == [Comparison(winner="3", loser="1"),
                                             Comparison(winner="3", loser="2")]
    assert comparisons_for_newest(batch[:1]) == []
    assert comparisons_for_newest([]) == []


def test_ties_make_no_comparison_and_equality_is_transitive():
    batch = [at("1", 0.5), Placement(interaction_id="2", equal_to="1"), at("3", 0.9),
             Placement(interaction_id="4", equal_to="2")]
    # 4 = 2 = 1, so only 3 ≻ 4 remains.
    assert comparisons_for_newest(batch) == [Comparison(winner="3", loser="4")]


def test_markers_sharing_a_position_without_equal_are_a_tie():
    assert comparisons_for_newest([at("1", 0.5), at("2", 0.5)]) == []


@pytest.mark.parametrize("position", [-0.01, 1.01, float("nan")])
def test_position_outside_the_scale_names_field_value_and_range(position):
    with pytest.raises(ValidationError, match=r"position = .* outside the scale \[0, 1\]"):
        at("1", position)


def test_scale_ends_are_allowed():
    assert comparisons_for_newest([at("1", 0.0), at("2", 1.0)]) == [
        Comparison(winner="2", loser="1")]


def test_equal_to_an_interaction_not_in_the_batch_is_an_error():
    with pytest.raises(ScaleError, match=r"equal_to = '9' is not an earlier interaction"):
        comparisons_for_newest([at("1", 0.5), Placement(interaction_id="2", equal_to="9")])


def test_a_second_placement_of_the_same_interaction_is_an_error():
    with pytest.raises(ScaleError, match=r"interaction_id = '1' is already placed"):
        comparisons_for_newest([at("1", 0.5), at("2", 0.3), at("1", 0.9)])


@pytest.mark.parametrize("kwargs", [{}, {"position": 0.5, "equal_to": "1"}])
def test_a_placement_needs_exactly_one_of_position_or_equal_to(kwargs):
    with pytest.raises(ValidationError, match="exactly one of position"):
        Placement(interaction_id="2", **kwargs)


def test_placing_on_itself_is_an_error():
    with pytest.raises(ValidationError, match="cannot be the interaction itself"):
        Placement(interaction_id="2", equal_to="2")


def test_a_comparison_of_an_interaction_with_itself_is_rejected():
    with pytest.raises(ValidationError, match="cannot beat itself"):
        Comparison(winner="1", loser="1")
