"""What ``handover report`` says, in the page and on the terminal: every validation score with its
n, no figure for a participant without the data for it (named instead of an empty plot), no
Markdown or reST markup, and whether each participant's validation was shown blind.

A study of three participants (short protocol, one validation pair each), stored by the session
engine and its simulated participant: V01 validated blind, V02 blind for its first validation trial
and not for the second (a restart with ``serve --unblind`` between them), V03 created and planned
but with no handover.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest
from support.engine import drive_until, short_config, step_once

from app.analysis.report import build_report
from app.cli import main
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from session_store.vocabulary import Phase

#: Markup a reader would see literally: reST ``x`` and roles, Markdown `x` and **x**.
MARKUP = re.compile(r"`|:[a-z]+:|\*\*")
#: Per participant, the dashboard's blinding when each of its two validation trials started.
BLINDING = {"V01": (True, True), "V02": (True, False)}


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    study = tmp_path_factory.mktemp("study")
    for seed, (code, (first, second)) in enumerate(BLINDING.items(), start=1):
        engine = SessionEngine.create(study, code, short_config(seed=seed))
        participant = SimulatedParticipant(seed)
        engine.set_blinding(first)
        while not (engine.state.phase is Phase.VALIDATION and engine.state.step is Step.READY):
            step_once(engine, participant)
        step_once(engine, participant)  # the pair's first trial
        engine.set_blinding(second)
        drive_until(engine, Step.DONE, participant)
        engine.close()
    engine = SessionEngine.create(study, "V03", short_config(seed=3))
    engine.plan_next()  # a learner snapshot, no handover
    engine.close()
    return study


def test_the_terminal_and_the_page_say_how_the_validation_was_shown_without_markup(study, tmp_path,
                                                                                   capsys):
    """Slow (~27 s in a loaded full run) as the module's first test: it pays for ``study`` (two
    short sessions through the real learner and a third planned) and runs ``handover report``."""
    assert main(["report", str(study), "--out", str(tmp_path / "r")]) == 0
    terminal = capsys.readouterr()
    page = (tmp_path / "r" / "report.html").read_text()
    text = re.sub(r"<[^>]+>", " ", re.sub(r"<(style|figure)\b.*?</\1>", "", page, flags=re.S))
    assert not MARKUP.search(terminal.out + terminal.err), terminal
    assert not MARKUP.search(text), MARKUP.findall(text)
    assert terminal.out.splitlines()[1].startswith("Simulated study: every answer in it")  # no person
    assert ("warning: V02: validation partly blind: 1 of 2 validation trials (serve --unblind for "
            "the rest)") in terminal.err and "V01" not in terminal.err
    assert ("V02: validation partly blind: 1 of 2 validation trials (serve --unblind for the "
            "rest): the dashboard showed the experimenter which trial of a pair was θ*") in text
    sessions = pd.read_csv(tmp_path / "r" / "tables" / "sessions.csv").set_index("participant")
    assert sessions["validation_blinding"].to_dict() == {
        "V01": "blind", "V02": "partly blind: 1 of 2 validation trials (serve --unblind for the rest)",
        "V03": "no validation trial yet"}


def test_a_participant_without_data_is_left_out_of_the_figures_and_every_score_has_its_n(
        study, tmp_path):
    """Slow: a report of the module's study with every figure drawn (Fig. 4 and the learning
    curve of each participant, the replays of the safety record's extremes), each saved twice."""
    report = build_report(study, tmp_path / "r", include_simulated=True)
    assert {name for name in report.figures if not name.startswith("safety-")} == \
        {"fig4-V01", "fig4-V02", "learning-V01", "learning-V02"}
    # the replays of the safety record's extremes are of trials that have samples: V03 has none
    replayed = {name.split("-")[1] for name in report.figures if name.startswith("safety-")}
    assert replayed and replayed <= {"V01", "V02"}
    page = report.html.read_text()
    assert ("Not drawn for V03: no completed handover before the validation, or no learner "
            "update.") in page
    assert "Not drawn for V03: no completed validation trial." in page
    scores = re.findall(r"<td>(\*?\d+ % of \d+ rated pairs?)</td>", page)
    assert len(scores) == 2 and all(s.endswith("of 1 rated pair") for s in scores), scores
