"""Issue 45, item 5: the study plan's counterbalanced assignment (``[study]``, app/protocol/design.py).
Balanced at every point (permuted blocks), the same for the same seed, extended (not reshuffled) by a
larger plan; within-subjects sessions follow each person's order; where a study stands against its
plan — the groups' counts, the next proposal, every deviation — is computed from what each
participant recorded."""

from __future__ import annotations

from collections import Counter

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from app.protocol.design import Participant, PlanStatus, StudyPlan, group_name
from app.session.config import LabConfig
from robot_io.hands.simulated_hand import Scenario

S, P = Scenario.STRAIGHTFORWARD, Scenario.PERTURBED


@given(design=st.sampled_from(["between", "within"]), size=st.integers(1, 30),
       seed=st.integers(0, 2**63 - 1))
def test_the_sequence_is_balanced_in_every_block_and_seeded(design, size, seed):
    plan = StudyPlan(design=design, group_size=size, seed=seed)
    sequence, groups = plan.sequence(), plan.groups()
    assert len(sequence) == size * len(groups)
    for start in range(0, len(sequence), len(groups)):  # each block holds every group once
        assert sorted(sequence[start:start + len(groups)]) == sorted(groups)
    assert plan.sequence() == sequence
    larger = StudyPlan(design=design, group_size=size + 3, seed=seed)
    assert larger.sequence()[:len(sequence)] == sequence  # a larger plan extends it


def test_within_each_persons_sessions_follow_their_order():
    plan = StudyPlan(design="within", group_size=3, seed=11)
    proposals = [plan.proposal(n) for n in range(1, plan.sessions + 1)]
    assert plan.sessions == 12 and plan.proposal(13) is None
    for person in range(1, 7):
        first, second = proposals[2 * person - 2], proposals[2 * person - 1]
        assert (first.person, first.session, second.person, second.session) == \
            (person, 1, person, 2)
        assert first.group == second.group == group_name((first.proposed, second.proposed))
    assert Counter(p.group for p in proposals[::2]) == {"straightforward → perturbed": 3,
                                                        "perturbed → straightforward": 3}


def participants(plan: StudyPlan, scenarios: list[Scenario]) -> list[Participant]:
    """Participants created one after the other under ``plan``, running ``scenarios``."""
    return [Participant(code=f"P{n:02d}", scenario=scenario, assignment=plan.proposal(n))
            for n, scenario in enumerate(scenarios, start=1)]


def test_the_status_counts_the_groups_and_proposes_the_next():
    plan = StudyPlan(design="between", group_size=4, seed=7)
    proposed = [plan.proposal(n).proposed for n in range(1, 9)]
    status = PlanStatus.of(plan, participants(plan, proposed[:5]))
    assert status.next == plan.proposal(6) and status.deviations == []
    assert sum(status.counts.values()) == 5 and max(status.counts.values()) == 3
    full = PlanStatus.of(plan, participants(plan, proposed))
    assert full.next is None and full.counts == {"straightforward": 4, "perturbed": 4}
    assert full.counts_words() == "straightforward 4 of 4, perturbed 4 of 4"
    assert full.choice_words(S) is None


def test_every_deviation_is_named():
    plan = StudyPlan(design="between", group_size=2, seed=7)
    proposed = [plan.proposal(n).proposed for n in range(1, 5)]
    swapped = S if proposed[3] is P else P
    study = participants(plan, [*proposed[:3], swapped])
    other = StudyPlan(design="between", group_size=2, seed=8)
    study += [Participant(code="X01", scenario=P, assignment=None),
              Participant(code="X02", scenario=S, assignment=other.proposal(1)),
              Participant(code="X03", scenario=proposed[0], assignment=plan.proposal(1))]
    status = PlanStatus.of(plan, study)
    assert status.deviations == [
        "P01: the plan's session 1 was given twice",
        f"P04: {swapped.value}, the plan proposed {proposed[3].value} (participant 4 of 4: "
        f"{proposed[3].value})",
        "X01: created outside the study plan (perturbed, chosen by hand)",
        "X02: created under another study plan (between-subjects, 2 groups of 2 participants "
        "(straightforward, perturbed), seed 8)",
        "X03: the plan's session 1 was given twice",
        f"{swapped.value}: 3 of 2 planned"]
    assert status.choice_words(P if status.next is None else status.next.proposed) is None
    within = StudyPlan(design="within", group_size=2, seed=3)
    skipped = [Participant(code=f"W{n}", scenario=within.proposal(n).proposed,
                           assignment=within.proposal(n)) for n in (1, 3, 4)]
    assert PlanStatus.of(within, skipped).deviations == ["person 1: 1 of 2 sessions"]


def test_the_lab_file_names_a_bad_study_plan():
    with pytest.raises(ValidationError, match=r"study\.design"):
        LabConfig.model_validate({"study": {"design": "mixed", "group_size": 8, "seed": 1}})
    with pytest.raises(ValidationError, match="names one twice"):
        LabConfig.model_validate({"study": {"design": "between", "group_size": 8, "seed": 1,
                                            "scenarios": ["perturbed", "perturbed"]}})
    with pytest.raises(ValidationError, match=r"study\.seed"):
        LabConfig.model_validate({"study": {"design": "between", "group_size": 8}})
    assert LabConfig().study is None  # no plan unless the lab writes one
