"""Parameter box normalisation and the paper's batch schedule."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from app.learning.errors import ParameterBoxError
from app.learning.models import ParameterBox, SlotKind
from app.learning.planner import PAPER_SESSION_SCHEDULE, BatchSchedule

#: Table I's box, written out here: app.learning must not import robot_io.
TABLE_I = {"a": (1.0, 10.0), "delta": (-1.0, 1.0), "k": (0.01, 15.0)}


def test_box_normalises_with_its_fixed_bounds_and_back():
    box = ParameterBox.from_bounds(TABLE_I)
    assert box.to_unit({"a": 1.0, "delta": 0.0, "k": 15.0}) == [0.0, 0.5, 1.0]
    theta = {"a": 4.0, "delta": -0.25, "k": 7.5}
    back = box.from_unit(box.to_unit(theta))
    assert back == pytest.approx(theta)


def test_point_outside_the_box_names_parameter_value_and_range():
    box = ParameterBox.from_bounds(TABLE_I)
    with pytest.raises(ParameterBoxError, match=r"theta.k = 16.0 is outside .* \[0.01, 15.0\]"):
        box.to_unit({"a": 1.0, "delta": 0.0, "k": 16.0})
    with pytest.raises(ParameterBoxError, match="parameters"):
        box.to_unit({"a": 1.0, "delta": 0.0})


def test_malformed_boxes_are_rejected():
    with pytest.raises(ValidationError, match=r"bounds of a = \[2.0, 1.0\] .* lower < upper"):
        ParameterBox.from_bounds({"a": (2.0, 1.0)})
    with pytest.raises(ValidationError, match="one bound per name"):
        ParameterBox(names=("a", "b"), lower=(0.0,), upper=(1.0, 1.0))


@pytest.mark.parametrize(("q", "interactions"), [(2, 45), (5, 30)])
def test_simulation_schedule_has_25_unique_points(q, interactions):
    schedule = BatchSchedule(n_initial=5, q=q, n_unique=25)
    slots = schedule.slots()
    assert len(slots) == schedule.n_interactions == interactions
    new = [s for s in slots if s.kind in (SlotKind.INITIAL, SlotKind.QUERY)]
    assert len(new) == 25
    assert [s.kind for s in slots[:5]] == [SlotKind.INITIAL] * 5
    for batch in range(1, schedule.n_batches + 1):
        kinds = [s.kind for s in slots if s.batch == batch]
        assert kinds[0] is SlotKind.BEST
        assert set(kinds[1:]) == {SlotKind.QUERY}
        assert [s.position for s in slots if s.batch == batch] == list(range(1, len(kinds) + 1))
    assert schedule.slot(interactions).kind is SlotKind.DONE


def test_human_study_schedule_is_5_random_then_4_batches_of_5():
    schedule = PAPER_SESSION_SCHEDULE
    assert schedule.n_initial == 5 and schedule.q == 5
    assert schedule.n_batches == 4
    assert schedule.n_interactions == 25


def test_a_batch_needs_room_for_a_query():
    with pytest.raises(ValidationError, match="q"):
        BatchSchedule(q=1)
