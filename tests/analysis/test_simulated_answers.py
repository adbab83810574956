"""Issue 45, item 1: the report says who gave every answer. Per participant, ``tables/learning.csv``
and the page count each kind of answer — placements, hints, validation ratings, the questionnaire —
by the participant, the experimenter on their behalf and the simulated participant; a participant
whose learning used the simulated participant's answers is marked § wherever their results appear
and left out of the paper's tables (Tables II–IV and the tests) unless ``--include-simulated``; a
study in which every answer is the simulated participant's (a pilot, a demo, ``run-session --auto``)
is reported whole, under a banner that says so.

Four participants of the short protocol (6 placements, 1 validation pair, 3 answers), driven by the
session engine: H01 and P01 answer everything themselves; M01's first placement is entered by the
experimenter and its learning batch placed by the simulated participant; C01 gives coactive hints,
4 of its 6 by the simulated participant."""

from __future__ import annotations

import html
import re
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest
from support.engine import SHORT_PROTOCOL, brief_config, drive_until, study_config

from app.analysis.report import build_report
from app.cli import main
from app.protocol.auto import act_once
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import SessionState, Step
from robot_io.hands.simulated_hand import Scenario
from session_store.vocabulary import Phase, Rater

PERSON, BEHALF, SIMULATED = Rater.PARTICIPANT, Rater.EXPERIMENTER, Rater.SIMULATED_PARTICIPANT


def mixed(state: SessionState) -> Rater:
    """M01: the experimenter enters the first placement, the simulated participant places the
    learning batch, the person does the rest."""
    slot = state.slot
    if state.step is Step.PLACE and slot is not None:
        return BEHALF if slot.interaction == 1 else SIMULATED if slot.phase is Phase.LEARNING \
            else PERSON
    return PERSON


def hinted(state: SessionState) -> Rater:
    """C01: the person hints after the first two handovers, the simulated participant after the
    others."""
    slot = state.slot
    return SIMULATED if state.step is Step.HINT and slot is not None and slot.interaction > 2 \
        else PERSON


PARTICIPANTS: dict[str, tuple[Scenario, bool, Callable[[SessionState], Rater]]] = {
    "H01": (Scenario.STRAIGHTFORWARD, False, lambda state: PERSON),
    "M01": (Scenario.STRAIGHTFORWARD, False, mixed),
    "P01": (Scenario.PERTURBED, False, lambda state: PERSON),
    "C01": (Scenario.PERTURBED, True, hinted),
}


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    study = tmp_path_factory.mktemp("study")
    for seed, (code, (scenario, coactive, who)) in enumerate(PARTICIPANTS.items(), start=1):
        engine = SessionEngine.create(study, code, study_config(seed, scenario, **SHORT_PROTOCOL,
                                                                coactive=coactive))
        participant = SimulatedParticipant(seed)
        while engine.state.step is not Step.DONE:
            act_once(engine, participant, who(engine.state))
        engine.close()
    return study


def text_of(page: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", " ", re.sub(r"<(style|figure)\b.*?</\1>", "", page,
                                                         flags=re.S)))


@pytest.fixture(scope="module")
def report(study, tmp_path_factory):
    """``study``'s report as ``handover report`` makes it by default: the tests that read it share
    one (a report draws the figures of each of the four participants)."""
    return build_report(study, tmp_path_factory.mktemp("report"))


def test_learning_csv_counts_who_gave_each_kind_of_answer(report):
    """Slow (~20 s in a loaded full run) as the module's first test: it pays for the ``study``
    fixture, four whole sessions of the short protocol, each with its learner process, and for
    ``report``."""
    table = pd.read_csv(report.tables["learning"]).set_index("participant")
    m01, c01, h01 = table.loc["M01"], table.loc["C01"], table.loc["H01"]
    assert (m01["placements_participant"], m01["placements_experimenter"],
            m01["placements_simulated"]) == (2, 1, 3)
    assert (m01["validation_participant"], m01["questionnaire_participant"]) == (1, 3)
    assert (c01["hints_participant"], c01["hints_simulated"], c01["placements_participant"]) == \
        (2, 4, 6)
    assert (h01["placements_participant"], h01["placements_simulated"], h01["hints_participant"]) \
        == (6, 0, 0)
    assert table["simulated_learning"].to_dict() == {"H01": False, "M01": True, "P01": False,
                                                     "C01": True}


def test_a_participant_whose_learning_was_simulated_is_left_out_and_marked(report):
    assert set(pd.read_csv(report.tables["table2_straightforward"])["participant"]) == {"H01"}
    assert set(pd.read_csv(report.tables["table3_perturbed"])["participant"]) == {"P01"}
    assert set(pd.read_csv(report.tables["table4_survey"])["participant"]) == {"H01", "P01"}
    assert {t.n_total for t in report.tests if t.test == "mann-whitney-u"} == {2}
    assert not report.counting.simulated_study
    assert report.counting.simulated_learning == {
        "M01": "3 of 6 placements by the simulated participant",
        "C01": "4 of 6 hints by the simulated participant"}
    assert "left out of Tables II–IV and the tests: C01, M01" in report.ratings_counted
    page = text_of(report.html.read_text())
    assert ("M01 §: learning used the simulated participant's answers (3 of 6 placements by the "
            "simulated participant); left out of Tables II–IV and the tests (handover report "
            "--include-simulated includes it)") in page
    assert "M01 §" in page.split("Sessions", 1)[1].split("Validation (Sect. VI-A)")[0]
    who = page.split("Who gave the answers")[1].split("Learning:")[0]
    assert "M01 § 2 participant, 1 experimenter, 3 simulated" in re.sub(r"\s+", " ", who)


def test_include_simulated_counts_them_marked(study, tmp_path):
    """Slow (~25 s in a loaded full run): the report of the module's four participants with the
    simulated ones counted (its figures)."""
    report = build_report(study, tmp_path, include_simulated=True)
    assert set(pd.read_csv(report.tables["table2_straightforward"])["participant"]) == \
        {"H01", "M01"}
    scores = pd.read_csv(report.tables["table2_straightforward"]).set_index("participant")
    assert scores["simulated_learning"].to_dict() == {"H01": False, "M01": True}
    tables = text_of(report.html.read_text()).split("Table II: validation results")[1]
    assert "M01 §" in tables


def test_the_terminal_warns_of_each_participant_left_out(study, tmp_path, capsys):
    """Slow (~27 s in a loaded full run): ``handover report`` on the module's four participants.
    A report's figures (matplotlib, each saved as PNG and SVG) are most of its CPU: a report of
    three short sessions took 8-11 CPU-s on a machine whose calibration loop took 2.6-4.4 CPU-s."""
    assert main(["report", str(study), "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert ("warning: M01: learning used the simulated participant's answers (3 of 6 placements by "
            "the simulated participant); left out of Tables II–IV and the tests "
            "(handover report --include-simulated includes it)") in err


def test_a_study_of_the_simulated_participant_alone_is_reported_under_a_banner(tmp_path):
    """Slow (~24 s in a loaded full run): two brief sessions through the real learner and their
    report (its figures)."""
    study = tmp_path / "pilot"
    for seed, code in enumerate(("S01", "S02"), start=1):
        engine = SessionEngine.create(study, code, brief_config(seed))
        drive_until(engine, Step.DONE)
        engine.close()
    report = build_report(study, tmp_path / "report")
    assert report.counting.simulated_study and report.counting.marked == []
    page = text_of(report.html.read_text())
    banner = ("Simulated study: every answer in it (placements, hints, validation ratings, "
              "questionnaire) was given by the simulated participant")
    assert page.index(banner) < page.index("Sessions")
    assert set(pd.read_csv(report.tables["table4_survey"])["participant"]) == {"S01", "S02"}
    assert "S01 §" not in page and "S02 §" not in page  # the banner says it of everyone
