"""The questionnaire is one list (``session_store.vocabulary.QUESTIONS``): a question added there is
asked on the tablet, counted on the dashboard, stored, exported, and reported in Table IV, its
tests and its notes, with nothing else changed."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pandas as pd
import pytest
from support.engine import brief_config, drive_until

from app.analysis.report import build_report
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.session.runner import RunnerView
from app.ui.questionnaire import Draft
from app.ui.status_text import progress_markdown
from app.ui.tablet import answer_options, question_html, screen_for
from session_store import vocabulary
from session_store.export import export_study, read_table
from session_store.vocabulary import Question

#: The question a lab adds: numeric, with a hypothesis (a sign test) and the scenarios compared.
Q4 = Question(id="Q4", text="Would you take an object from this robot again?",
              paper_text="I would accept further handovers from the robot.",
              answers=("Not at all", "2", "3", "4", "Gladly"), numeric=True, above=3.0)


@pytest.fixture
def fourth_question(monkeypatch: pytest.MonkeyPatch) -> Question:
    monkeypatch.setattr(vocabulary, "QUESTIONS", (*vocabulary.QUESTIONS, Q4))
    return Q4


def test_a_fourth_question_reaches_the_tablet_the_store_the_export_and_the_report(
        fourth_question: Question, tmp_path: Path):
    """Slow: a brief session through the engine and its real learner, then the study's export
    and its report with every figure."""
    study = tmp_path / "study"
    config = brief_config(seed=3)
    engine = SessionEngine.create(study, "P01", config)
    participant = SimulatedParticipant(config.seed)
    drive_until(engine, Step.ANSWER, participant)

    view = RunnerView(code="P01", scenario=config.scenario, interactions=3, state=engine.state)
    screen = screen_for(view)
    assert (screen.kind, screen.questions) == ("question", ("Q1", "Q2", "Q3", "Q4"))
    last = Draft(questions=screen.questions, page=3)
    assert "Question 4 of 4" in question_html(last)
    assert fourth_question.text in question_html(last)
    assert answer_options("Q4")[-1] == ("5 – Gladly", "5")
    assert progress_markdown(view).endswith("Questionnaire · 0 of 4 answered")

    drive_until(engine, Step.DONE, participant)
    engine.close()
    with sqlite3.connect(study / "P01.sqlite") as db:
        stored = dict(db.execute("SELECT question, value FROM answers").fetchall())
    assert list(stored) == ["Q1", "Q2", "Q3", "Q4"]
    assert stored["Q4"] in {"3", "4", "5"}

    export_study(study, tmp_path / "export")
    exported = read_table(tmp_path / "export", "answers")
    assert exported.set_index("question")["value"].to_dict() == stored

    report = build_report(study, tmp_path / "report", include_simulated=True)
    table4 = pd.read_csv(report.tables["table4_survey"])
    assert list(table4.columns[-4:]) == ["Q1", "Q2", "Q3", "Q4"]
    assert table4.loc[0, "Q4"] == int(stored["Q4"])
    assert [t.name for t in report.tests if t.name.startswith("Q4")] == [
        "Q4 answers > 3 (Table IV)", "Q4: straightforward vs perturbed"]
    assert next(t for t in report.tests if t.name.startswith("Q4 answers")).n_total == 1
    page = report.html.read_text()
    assert "Q4: I would accept further handovers from the robot (1–5)." in page
    assert "<th>Q4</th>" in page

