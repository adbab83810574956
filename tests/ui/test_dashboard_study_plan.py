"""Issue 45, item 5: counterbalancing from the dashboard. With a study plan in lab.toml (``[study]``,
between-subjects, 2 groups of 4, seed 7) the Study panel says the design, the groups' counts and
what the plan proposes for the next participant; its Scenario field starts there; choosing the other
scenario is named as a deviation before Create. Eight participants created from a real browser as
the plan proposes make two balanced groups, each with its assignment recorded, and the report's
design line says so. Without a plan nothing picks a condition: the field reads "— choose —" and a
new code is refused until one is chosen.

The plan's test takes about 90 s: every Create starts a rig process (mock arm) and the learner plans
the first handover before End closes them, eight times, as between participants in a lab.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    BRIEF_TOML,
    LEARNER_CEILING_MS,
    choose,
    chromium,
    click,
    fill,
    labelled,
    open_page,
    serve,
    shot,
    unlock_dashboard,
    wait_function,
    wait_gone,
    wait_text,
)

from app.analysis.report import build_report
from app.protocol.design import StudyPlan, recorded_assignment
from app.ui.participant_form import CHOOSE
from session_store.catalog import stored_configs

pytestmark = [pytest.mark.browser, pytest.mark.slow]

PLAN = StudyPlan(design="between", group_size=4, seed=7)
PLAN_TOML = '[study]\ndesign = "between"\ngroup_size = 4\nseed = 7\n'
SHOTS = Path("/tmp/study-plan-shots")


def wait_first_plan(dashboard: Page) -> None:
    """Wait until the learner has planned the open participant's first handover: End session and
    Ctrl-C wait for it, as they do for the experimenter (its first start may take a minute on a
    loaded machine)."""
    wait_function(dashboard, "() => document.body.innerText.includes('Ready, but')",
                  "the first handover planned", timeout_ms=LEARNER_CEILING_MS)


def test_eight_participants_created_as_the_plan_proposes_make_balanced_groups(tmp_path: Path):
    """Slow: eight participants created one after the other on the dashboard, each opened (its
    learner process and first plan) and ended, as the plan's counts need."""
    proposed = [PLAN.proposal(n).proposed.value for n in range(1, 9)]
    with serve(tmp_path, protocol_toml=BRIEF_TOML, tables=PLAN_TOML) as served, \
            chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=(1280, 720))
        unlock_dashboard(dashboard)
        for n, scenario in enumerate(proposed, start=1):
            wait_text(dashboard, f"Next: participant {n} of 8: {scenario}")
            assert labelled(dashboard, "Scenario").input_value() == scenario
            if n == 3:
                other = "perturbed" if scenario == "straightforward" else "straightforward"
                choose(dashboard, "Scenario", other)
                wait_text(dashboard, f"the plan proposes {scenario}: {other} is recorded as a "
                                     "deviation")
                shot(dashboard, SHOTS, "deviation-named")
                choose(dashboard, "Scenario", scenario)
                wait_gone(dashboard, "recorded as a deviation")
            fill(dashboard, "Code", f"P{n:02d}")
            click(dashboard, "Create or resume")
            wait_first_plan(dashboard)
            click(dashboard, "End session")
            wait_text(dashboard, "No participant open")
        wait_text(dashboard, "so far straightforward 4 of 4, perturbed 4 of 4")
        wait_text(dashboard, "every session of the plan (8) is created")
        assert labelled(dashboard, "Scenario").input_value() == CHOOSE
        shot(dashboard, SHOTS, "eight-created")
        served.shutdown()
    configs = stored_configs(served.study)
    assert [(configs[f"P{n:02d}"]["scenario"], recorded_assignment(configs[f"P{n:02d}"]).position)
            for n in range(1, 9)] == list(zip(proposed, range(1, 9), strict=True))
    report = build_report(served.study, tmp_path / "report")
    assert report.design.line == (
        "Design: between-subjects, 2 groups of 4 participants (straightforward, perturbed), seed 7 "
        "(the study plan, [study] of lab.toml); as run: straightforward 4 of 4, perturbed 4 of 4; "
        "no deviation from the plan.")
    assert report.design.line in report.html.read_text()


def test_without_a_plan_no_scenario_is_chosen_for_the_experimenter(tmp_path: Path):
    """Slow: a `serve` and the dashboard's page in Chromium, unlocked, for one refused creation."""
    with serve(tmp_path, protocol_toml=BRIEF_TOML) as served, chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=(1280, 720))
        unlock_dashboard(dashboard)
        assert labelled(dashboard, "Scenario").input_value() == CHOOSE
        fill(dashboard, "Code", "P01")
        click(dashboard, "Create or resume")
        wait_text(dashboard, "participant 'P01' has no session yet: choose a scenario")
        assert not served.study.exists() or not list(served.study.glob("*.sqlite"))
        choose(dashboard, "Scenario", "straightforward")  # the experimenter's choice is taken
        served.shutdown()
