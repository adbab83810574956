"""The report's design line: the study plan the participants were created under (``[study]``,
recorded with each of them: app/protocol/design.py), the groups as they ran, and every deviation
from the plan — a scenario other than the one proposed, a participant created without the plan or
under another, a group over its size, a within-subjects person with a session missing."""

from __future__ import annotations

import json

import pandas as pd
from pydantic import BaseModel

from app.protocol.design import PlanStatus, plan_participants, recorded_assignment

NO_PLAN = ("Design: no study plan recorded — the experimenter chose each participant's scenario "
           "([study] in lab.toml proposes a balanced, seeded assignment and records it).")
WITHIN_NOTE = (" Each person ran every scenario: the tests below compare the scenarios by Wilcoxon's "
               "signed-rank test paired by person, and the sign tests take each person once (the "
               "mean of their sessions).")


class StudyDesign(BaseModel):
    """The design in one line, and the deviations from the plan."""

    line: str
    deviations: list[str]
    #: within-subjects plan: participant → person, for the participants created under it (the
    #: tests pair their sessions); None for a between-subjects plan or none
    persons: dict[str, int] | None = None


def study_design(participants: pd.DataFrame) -> StudyDesign:
    """The design of the study whose ``participants`` table is given: the plan of the participant
    created last under one (a plan changed mid-study makes the earlier ones deviations)."""
    rows = participants.sort_values("created_at")
    configs = {row.participant: json.loads(row.config) for row in rows.itertuples()}
    plans = [a.plan for a in map(recorded_assignment, configs.values()) if a is not None]
    if not plans:
        return StudyDesign(line=NO_PLAN, deviations=[])
    plan = plans[-1]
    participants = plan_participants(configs)
    status = PlanStatus.of(plan, participants)
    deviations = status.deviations
    line = (f"Design: {plan.words()} (the study plan, [study] of lab.toml); as run: "
            f"{status.counts_words()}; "
            + (f"{len(deviations)} deviation{'' if len(deviations) == 1 else 's'} from the plan "
               "(under Data problems)." if deviations else "no deviation from the plan.")
            + (WITHIN_NOTE if plan.design == "within" else ""))
    persons = {p.code: p.assignment.person for p in participants if p.assignment is not None
               and p.assignment.plan == plan and p.assignment.person is not None}
    return StudyDesign(line=line, deviations=deviations,
                       persons=persons if plan.design == "within" else None)
