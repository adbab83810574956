"""The stages of the handover cycle are one list (``robot_io.stages.Stage``, in order) and their words
one table (``app.ui.stage_words``): every stage has its tablet screen and its dashboard words, in the
cycle's order, and the tablet and the dashboard show what the table says for each."""

from __future__ import annotations

import pytest

from app.protocol.plan import protocol_slots
from app.protocol.state import SessionState
from app.session.config import LabConfig
from app.session.runner import RunnerView
from app.ui.stage_words import CYCLE, INSTEAD_OF, STAGE_WORDS, stage_name
from app.ui.status_text import cycle_markdown, status_line
from app.ui.tablet import screen_for
from robot_io.hands.simulated_hand import Scenario
from robot_io.stages import AWAITS, Stage

SLOTS = protocol_slots(LabConfig().study_config(Scenario.PERTURBED, 0))


def running(stage: Stage) -> RunnerView:
    """The first trial of a session, in ``stage``."""
    return RunnerView(code="P07", scenario=Scenario.PERTURBED,
                      state=SessionState(slots=SLOTS, running_trial=1, stage=stage))


def test_every_stage_has_its_words_in_the_cycle_order():
    assert list(STAGE_WORDS) == list(Stage)
    dashboard = [words.dashboard for words in STAGE_WORDS.values()]
    assert all(dashboard) and len(set(dashboard)) == len(dashboard)
    assert set(CYCLE) | set(INSTEAD_OF) == set(Stage)


def test_the_tablet_waits_before_go_cues_from_go_and_says_back_after_the_hold():
    order = list(Stage)
    before_go = order[:order.index(Stage.GO)]
    assert [s for s in order if STAGE_WORDS[s].tablet == "wait"] == before_go
    assert [STAGE_WORDS[s].tablet for s in order[order.index(Stage.GO):]] == sorted(
        (STAGE_WORDS[s].tablet for s in order[order.index(Stage.GO):]),
        key=["go", "back"].index), "the tablet goes from Go! to 'moving back', never back to Go!"
    assert set(AWAITS) <= set(before_go), "the experimenter confirms before the cue"


@pytest.mark.parametrize("stage", list(Stage))
def test_the_tablet_and_the_dashboard_show_the_words_of_the_stage(stage: Stage):
    view = running(stage)
    words = STAGE_WORDS[stage]
    assert screen_for(view).kind == words.tablet
    assert status_line(view) == f"**Handover running** — {words.dashboard}."
    line = cycle_markdown(view).split("  \n")[0]
    assert line.count("**[") == 1 and f"**[{stage_name(stage)}]**" in line
    assert line == "cycle: " + " → ".join(
        f"**[{stage_name(stage)}]**" if s in (stage, INSTEAD_OF.get(stage)) else stage_name(s)
        for s in CYCLE)
