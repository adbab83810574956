"""The stages of the handover cycle and their words are one table (``robot_io.control.stages``, in
order): every stage has its tablet screen and its dashboard words, in the cycle's order, and the
tablet and the dashboard show what the table says for each."""

from __future__ import annotations

import pytest

from app.protocol.plan import protocol_slots
from app.protocol.state import SessionState
from app.session.config import LabConfig
from app.session.runner import RunnerView
from app.ui.stage_words import cycle_line, instead_of, stage_name, stage_words
from app.ui.status_text import cycle_markdown, status_line
from app.ui.tablet import screen_for
from robot_io.control.stages import PAPER_CYCLE, Confirmation, Part, Stage, StageRow
from robot_io.hands.simulated_hand import Scenario

SLOTS = protocol_slots(LabConfig().study_config(Scenario.PERTURBED, 0))


def running(stage: Stage) -> RunnerView:
    """The first trial of a session, in ``stage``."""
    return RunnerView(code="P07", scenario=Scenario.PERTURBED,
                      state=SessionState(slots=SLOTS, running_trial=1, stage=stage))


def test_every_stage_has_its_words_in_the_cycle_order():
    assert PAPER_CYCLE.names == tuple(Stage)
    dashboard = [stage_words(stage).dashboard for stage in Stage]
    assert all(dashboard) and len(set(dashboard)) == len(dashboard)
    assert set(cycle_line()) | set(instead_of()) == set(Stage)


def test_the_tablet_waits_before_go_cues_from_go_and_says_back_after_the_hold():
    order = list(Stage)
    before_go = order[:order.index(Stage.GO)]
    assert [s for s in order if stage_words(s).tablet == "wait"] == before_go
    assert [stage_words(s).tablet for s in order[order.index(Stage.GO):]] == sorted(
        (stage_words(s).tablet for s in order[order.index(Stage.GO):]),
        key=["go", "back"].index), "the tablet goes from Go! to 'moving back', never back to Go!"
    assert {row.name for row in PAPER_CYCLE.gated} <= set(before_go), \
        "the experimenter confirms before the cue"


def test_a_confirmation_while_the_arm_streams_is_refused():
    with pytest.raises(ValueError, match="a gate and work of run_cycle belong to a stage before Go"):
        StageRow(name="gaze", part=Part.STREAMED, entry="", does="", exit="", says="",
                 gate=Confirmation(button="Gaze", asks="wait for the gaze"))


@pytest.mark.parametrize("stage", list(Stage))
def test_the_tablet_and_the_dashboard_show_the_words_of_the_stage(stage: Stage):
    view = running(stage)
    words = stage_words(stage)
    assert screen_for(view).kind == words.tablet
    assert status_line(view) == f"**Handover running** — {words.dashboard}."
    line = cycle_markdown(view).split("  \n")[0]
    assert line.count("**[") == 1 and f"**[{stage_name(stage)}]**" in line
    assert line == "cycle: " + " → ".join(
        f"**[{stage_name(stage)}]**" if s in (stage, instead_of().get(stage)) else stage_name(s)
        for s in cycle_line())
