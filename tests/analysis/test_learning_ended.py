"""Issue 45, item 3: the report's "Learning ended" says what happened to each participant's learning
— early (and why), at the schedule's end, interrupted (after how many of its handovers, where the
session stopped) or not started — never "at the schedule's end — the fixed schedule" for a session
that stopped before learning ended.

Three participants of the short protocol (3 initial handovers + 1 learning batch of 3 = 6 learned
from, 9 in all): D01 complete, I01 paused by the experimenter after 4 handovers, N01 created and
planned with no handover."""

from __future__ import annotations

import html

import pandas as pd
import pytest
from support.engine import closed_session, new_engine, step_once

from app.analysis.report import build_report
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step


@pytest.fixture(scope="module")
def learning(tmp_path_factory) -> tuple[pd.DataFrame, str]:
    study = tmp_path_factory.mktemp("study")
    closed_session(study, "D01", seed=1)
    engine = new_engine(study, "I01", seed=2)
    participant = SimulatedParticipant(2)
    while not (engine.state.completed == 4 and engine.state.step is Step.READY):
        step_once(engine, participant)
    engine.pause("the participant had to leave")
    engine.close()
    engine = new_engine(study, "N01", seed=3)
    engine.plan_next()
    engine.close()
    report = build_report(study, tmp_path_factory.mktemp("report"), include_simulated=True)
    return pd.read_csv(report.tables["learning"]).set_index("participant"), \
        report.html.read_text()


def test_each_participants_learning_ended_as_it_did(learning):
    """Slow (~23 s in a loaded full run) as the module's first test: it pays for ``learning``, a
    short session to its end and one to its fourth handover through the real learner, and their
    report."""
    table, _ = learning
    assert table.loc["D01", "learning_ended"] == "at the schedule's end"
    assert table.loc["D01", "why"] == "the fixed schedule (no stopping rule)"
    assert table.loc["I01", "learning_ended"] == "interrupted after 4 of 6"
    assert table.loc["I01", "why"] == ("the session stopped before learning ended, at handover 5 "
                                       "of 9 (waiting for Start; paused: the participant had to "
                                       "leave)")
    assert table.loc["N01", "learning_ended"] == "not started"
    assert table.loc["N01", "why"] == "no handover was completed (waiting for Start)"
    assert table["learning_interactions"].to_dict() == {"D01": 6, "I01": 4, "N01": 0}


def test_the_page_says_it_in_the_same_words(learning):
    table, page = learning
    for code in ("I01", "N01"):
        assert html.escape(table.loc[code, "why"]) in page
    assert page.count("at the schedule&#x27;s end") == 1
