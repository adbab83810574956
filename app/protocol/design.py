"""Counterbalancing: the study plan (``[study]`` of lab.toml) and each new participant's assignment
(issue 45).

The paper assigned 16 people to two groups of 8, one per scenario (a between-subjects design). A
:class:`StudyPlan` names the design, the scenarios, the size of each group and a seed; from them a
balanced, seeded sequence of groups in **permuted blocks**: each block of as many participants as
there are groups holds every group once, in an order drawn from the seed, so the groups stay
balanced at every point of the study (a study stopped after 7 people has 4 and 3, never 7 and 0)
and the sequence does not depend on the group size (a larger plan extends it).

- ``design = "between"``: the groups are the scenarios; the n-th participant created under the
  plan is proposed the n-th group's scenario.
- ``design = "within"``: every person runs every scenario, one session each; the groups are the
  orders of the scenarios (every permutation). The sessions are numbered in the order they are
  created, a person's sessions one after the other: session n belongs to person ⌈n / k⌉ (k
  scenarios) and is proposed the scenario that comes next in that person's order.

The proposal is recorded with the participant (:class:`Assignment`, in its session plan) with the
scenario chosen, so a deviation is on record and the report flags it. Nothing here picks a scenario
silently: without a plan the experimenter chooses every scenario, and with one the dashboard and
``run-session`` say what the plan proposes.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from itertools import permutations
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from app.protocol.seeds import Seed
from robot_io.hands.simulated_hand import Scenario

Design = Literal["between", "within"]
DESIGN_WORDS = {"between": "between-subjects", "within": "within-subjects"}


def group_name(group: tuple[Scenario, ...]) -> str:
    """A group's name: its scenario, or its order of scenarios ("perturbed → straightforward")."""
    return " → ".join(s.value for s in group)


class StudyPlan(BaseModel):
    """``[study]``: the design, its scenarios, how many participants (between) or people (within)
    each group has, and the seed of the assignment."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    design: Design = Field(description="between: each participant runs one scenario (the "
                                       "paper's); within: each person runs every scenario, in a "
                                       "counterbalanced order")
    scenarios: tuple[Scenario, ...] = Field(
        (Scenario.STRAIGHTFORWARD, Scenario.PERTURBED), min_length=2,
        description="the conditions compared (default: both of the paper's)")
    group_size: int = Field(ge=1, le=1000, description="participants per scenario (between) or "
                                                       "people per order (within); paper: 8")
    seed: Seed

    @field_validator("scenarios")
    @classmethod
    def _distinct(cls, scenarios: tuple[Scenario, ...]) -> tuple[Scenario, ...]:
        if len(set(scenarios)) != len(scenarios):
            raise ValueError(f"scenarios = {[s.value for s in scenarios]} names one twice")
        return scenarios

    def groups(self) -> list[tuple[Scenario, ...]]:
        """The groups: one per scenario (between) or per order of the scenarios (within)."""
        if self.design == "between":
            return [(s,) for s in self.scenarios]
        return list(permutations(self.scenarios))

    def sequence(self) -> list[tuple[Scenario, ...]]:
        """The group of each participant (between) or person (within), in permuted blocks."""
        groups = self.groups()
        rng = np.random.default_rng([self.seed, 0xBA1A])
        return [groups[i] for _ in range(self.group_size) for i in rng.permutation(len(groups))]

    @property
    def sessions(self) -> int:
        """The sessions the plan holds: every person's every session."""
        per_person = 1 if self.design == "between" else len(self.scenarios)
        return self.group_size * len(self.groups()) * per_person

    def proposal(self, position: int) -> Assignment | None:
        """What the plan proposes for its ``position``-th session (1-based); None past its end."""
        if not 1 <= position <= self.sessions:
            return None
        per_person = 1 if self.design == "between" else len(self.scenarios)
        person, session = divmod(position - 1, per_person)
        group = self.sequence()[person]
        return Assignment(plan=self, position=position, group=group_name(group),
                          proposed=group[session],
                          person=None if self.design == "between" else person + 1,
                          session=None if self.design == "between" else session + 1)

    def words(self) -> str:
        """E.g. "between-subjects, 2 groups of 8 (straightforward, perturbed), seed 7"."""
        unit = "participants" if self.design == "between" else "people"
        return (f"{DESIGN_WORDS[self.design]}, {len(self.groups())} groups of {self.group_size} "
                f"{unit} ({', '.join(group_name(g) for g in self.groups())}), seed {self.seed}")


class Assignment(BaseModel):
    """What the study plan proposed for a participant's session, recorded with it."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    plan: StudyPlan
    position: int = Field(ge=1, description="the n-th session created under the plan")
    group: str = Field(description="its group: the scenario, or the person's order (within)")
    proposed: Scenario = Field(description="the scenario the plan proposed for this session")
    person: int | None = Field(None, ge=1, description="within: the person (1-based)")
    session: int | None = Field(None, ge=1, description="within: which of the person's sessions")

    def words(self) -> str:
        """E.g. "participant 6 of 16: perturbed" or "person 3, session 1 of 2 (order perturbed →
        straightforward): perturbed"."""
        if self.person is None:
            return f"participant {self.position} of {self.plan.sessions}: {self.proposed.value}"
        return (f"person {self.person}, session {self.session} of {len(self.plan.scenarios)} "
                f"(order {self.group}): {self.proposed.value}")


def recorded_assignment(config: Mapping[str, Any]) -> Assignment | None:
    """The assignment a stored session plan records (None: created without a study plan, or
    before plans were recorded)."""
    recorded = config.get("assignment")
    if recorded is None:
        return None
    try:
        return Assignment.model_validate(recorded)
    except ValidationError:
        return None


class Participant(BaseModel):
    """A participant of the study as the plan sees it: the scenario its session runs and the
    assignment recorded with it."""

    model_config = ConfigDict(frozen=True)

    code: str
    scenario: Scenario
    assignment: Assignment | None


def _missing_sessions(plan: StudyPlan, under: list[Participant]) -> list[str]:
    """Within: the people, before the latest, who did not run all their sessions."""
    sessions = Counter(p.assignment.person for p in under if p.assignment is not None)
    latest = max((person for person in sessions if person is not None), default=0)
    return [f"person {person}: {sessions[person]} of {len(plan.scenarios)} sessions"
            for person in range(1, latest) if sessions[person] < len(plan.scenarios)]


def plan_participants(configs: Mapping[str, Mapping[str, Any]]) -> list[Participant]:
    """The participants of stored session plans (code → plan, as ``stored_configs`` reads them),
    by code; a plan without a valid scenario is skipped (``doctor`` says what is wrong)."""
    participants = []
    for code, config in sorted(configs.items()):
        try:
            scenario = Scenario(str(config.get("scenario")))
        except ValueError:
            continue
        participants.append(Participant(code=code, scenario=scenario,
                                        assignment=recorded_assignment(config)))
    return participants


class PlanStatus(BaseModel):
    """Where a study stands against its plan: the groups' counts, the next proposal and the
    deviations."""

    model_config = ConfigDict(frozen=True)

    plan: StudyPlan
    next: Assignment | None  # None: every session of the plan is created
    counts: dict[str, int]  # group → participants (between) or people (within) so far
    deviations: list[str]

    @classmethod
    def of(cls, plan: StudyPlan, participants: list[Participant]) -> PlanStatus:
        """The study of ``participants`` against ``plan``."""
        under = [p for p in participants if p.assignment is not None and p.assignment.plan == plan]
        positions = Counter(p.assignment.position for p in under if p.assignment is not None)
        members: dict[str, set[int]] = {group_name(g): set() for g in plan.groups()}
        deviations = []
        for p in participants:
            a = p.assignment
            if a is None:
                deviations.append(f"{p.code}: created outside the study plan "
                                  f"({p.scenario.value}, chosen by hand)")
                continue
            if a.plan != plan:
                deviations.append(f"{p.code}: created under another study plan "
                                  f"({a.plan.words()})")
                continue
            group = p.scenario.value if plan.design == "between" else a.group  # as run
            members.setdefault(group, set()).add(a.person or a.position)
            if p.scenario is not a.proposed:
                deviations.append(f"{p.code}: {p.scenario.value}, the plan proposed "
                                  f"{a.proposed.value} ({a.words()})")
            if positions[a.position] > 1:
                deviations.append(f"{p.code}: the plan's session {a.position} was given twice")
        if plan.design == "within":
            deviations += _missing_sessions(plan, under)
        counts = {group: len(people) for group, people in members.items()}
        deviations += [f"{group}: {count} of {plan.group_size} planned" for group, count
                       in counts.items() if count > plan.group_size]
        return cls(plan=plan, next=plan.proposal(max(positions, default=0) + 1), counts=counts,
                   deviations=deviations)

    def counts_words(self) -> str:
        """E.g. "straightforward 3 of 8, perturbed 2 of 8"."""
        return ", ".join(f"{group} {count} of {self.plan.group_size}"
                         for group, count in self.counts.items())

    def next_words(self) -> str:
        """What the plan proposes next, e.g. "next: participant 6 of 16: perturbed"."""
        if self.next is None:
            return (f"every session of the plan ({self.plan.sessions}) is created: choose the "
                    "scenario of an extra participant (recorded outside the plan)")
        return f"next: {self.next.words()}"

    def choice_words(self, scenario: Scenario | None) -> str | None:
        """Why choosing ``scenario`` for the next participant deviates from the plan (None: it
        does not, or nothing is chosen)."""
        if self.next is None or scenario is None or scenario is self.next.proposed:
            return None
        return (f"the plan proposes {self.next.proposed.value}: {scenario.value} is recorded as a "
                "deviation")
