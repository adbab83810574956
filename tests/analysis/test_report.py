"""``handover report`` on a simulated study of 4 complete participants (2 per scenario, short
protocol) plus one who stopped mid-protocol: the report's tables must match the databases (read here
with plain sqlite3, not through the export), and bad input must be reported, not hidden."""

from __future__ import annotations

import json
import math
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support.engine import drive_until, short_config
from support.study import contents

from app.analysis.report import build_report
from app.analysis.trajectories import validation_distances
from app.cli import main
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario
from session_store.errors import StoreError
from session_store.export import load_study

COMPLETE = {"P01": Scenario.STRAIGHTFORWARD, "P02": Scenario.STRAIGHTFORWARD,
            "P03": Scenario.PERTURBED, "P04": Scenario.PERTURBED}
STOPPED = "P05"  # stopped when the questionnaire was due


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    study = tmp_path_factory.mktemp("study")
    for seed, (code, scenario) in enumerate(COMPLETE.items(), start=1):
        engine = SessionEngine.create(study, code, short_config(seed=seed, scenario=scenario))
        drive_until(engine, Step.DONE, SimulatedParticipant(seed))
        engine.close()
    engine = SessionEngine.create(study, STOPPED, short_config(seed=5, scenario=Scenario.PERTURBED))
    drive_until(engine, Step.ANSWER)
    engine.close()
    return study


@pytest.fixture(scope="module")
def report(study, tmp_path_factory):
    # Every rating of this study is the simulated participant's: count them.
    return build_report(study, tmp_path_factory.mktemp("report"), include_simulated=True)


def query(study: Path, code: str, sql: str) -> list[tuple]:
    with sqlite3.connect(study / f"{code}.sqlite") as conn:
        return conn.execute(sql).fetchall()


def csv(report, name: str) -> pd.DataFrame:
    return pd.read_csv(report.tables[name]).set_index("participant")


def test_tables_ii_iii_match_the_databases(study, report):
    """Slow as the module's first test: it builds the study the module reads (four short sessions
    and a fifth stopped, each with the real learner) and its report."""
    scores = pd.concat([csv(report, "table2_straightforward"), csv(report, "table3_perturbed")])
    assert set(csv(report, "table2_straightforward").index) == {"P01", "P02"}
    assert set(csv(report, "table3_perturbed").index) == {"P03", "P04", STOPPED}
    for code in COMPLETE:
        (star,) = query(study, code, "SELECT theta_star_a, theta_star_delta, theta_star_k FROM "
                                     "learner_snapshots ORDER BY after_interaction DESC LIMIT 1")
        best = set(query(study, code, "SELECT theta_a, theta_delta, theta_k FROM trials "
                                      "WHERE origin = 'best' AND phase = 'validation'"))
        assert best == {star}  # θ* is the θ of the validation pairs' learned trials
        row = scores.loc[code]
        assert (row["theta_a"], row["theta_delta"], row["theta_k"]) == pytest.approx(star)
        ratings = [r for (r,) in query(study, code, "SELECT learned_preferred FROM "
                                                    "validation_ratings")]
        assert row["pairs"] == len(ratings) == 1
        assert row["score_pct"] == pytest.approx(100 * sum(r == 1 for r in ratings) / len(ratings))
        assert row["equal"] == sum(r is None for r in ratings)
    assert math.isnan(scores.loc[STOPPED, "score_pct"]) and scores.loc[STOPPED, "pairs"] == 0


def test_survey_and_sessions_match_the_databases(study, report):
    survey = pd.read_csv(report.tables["table4_survey"], dtype=str, keep_default_na=False)
    survey, sessions = survey.set_index("participant"), csv(report, "sessions")
    for code in [*COMPLETE, STOPPED]:
        answers = dict(query(study, code, "SELECT question, value FROM answers"))
        for question in ("Q1", "Q2", "Q3"):
            assert survey.loc[code, question] == answers.get(question, "")
        ((completed,),) = query(study, code, "SELECT count(*) FROM trials "
                                             "WHERE outcome = 'completed'")
        ((config,),) = query(study, code, "SELECT config FROM participant")
        planned = short_config().interactions
        assert json.loads(config)["validation_batches"] == 1
        assert (sessions.loc[code, "completed"], sessions.loc[code, "planned"]) == (completed, planned)
        assert sessions.loc[code, "complete"] == (code != STOPPED)
    assert sessions.loc[STOPPED, "waiting_for"] == "answer"
    assert sessions.loc[STOPPED, "completed"] < short_config().interactions


def test_statistics_use_the_complete_sessions_only(report):
    stats = pd.read_csv(report.tables["statistics"])
    scores = pd.concat([csv(report, "table2_straightforward"), csv(report, "table3_perturbed")])
    complete = scores[scores["complete"]]
    above = int((complete["score_pct"] > 50).sum())
    below = int((complete["score_pct"] < 50).sum())
    validation = stats.iloc[0]
    assert (validation["n_total"], validation["n"]) == (len(COMPLETE), above + below)
    tail = sum(math.comb(above + below, i) for i in range(above, above + below + 1))
    assert validation["p_value"] == pytest.approx(tail / 2 ** (above + below))
    groups = json.loads(stats.iloc[2]["groups"])
    assert groups == {"straightforward": 2, "perturbed": 2}  # P05 (perturbed) left out
    assert report.incomplete == [STOPPED]


def test_fig4_data_are_the_stored_samples(study):
    tables = load_study(study, ["participants", "trials", "samples"],
                        sample_phases=["validation"]).tables
    distances = validation_distances(tables["participants"], tables["trials"], tables["samples"])
    goal = np.array(short_config().controller.scene.handover_point)
    code = "P03"
    (trial,) = query(study, code, "SELECT trial_index FROM trials WHERE phase = 'validation' "
                                  "AND origin = 'sobol'")
    xyz = np.array(query(study, code, f"SELECT measured_x, measured_y, measured_z FROM samples "
                                      f"WHERE trial_index = {trial[0]} ORDER BY cycle"))
    robot = distances[(distances["participant"] == code)
                      & (distances["trial_index"] == trial[0])]["robot"].to_numpy()
    expected = np.linalg.norm(xyz - goal, axis=1) / np.linalg.norm(xyz[0] - goal)
    np.testing.assert_allclose(robot, expected)
    assert set(distances["participant"]) == set(COMPLETE)  # P05 has no validation trial
    human = distances["human"].dropna()
    assert human.between(0, 2).all() and len(human) < len(distances)  # 100 Hz tracker


def test_figures_and_page(report):
    for code in COMPLETE:
        for kind in ("fig4", "learning"):
            files = report.figures[f"{kind}-{code}"]
            assert files.png.stat().st_size > 10_000 and files.svg.read_text().startswith("<?xml")
    assert f"fig4-{STOPPED}" not in report.figures and f"learning-{STOPPED}" in report.figures
    page = report.html.read_text()
    assert page.count("data:image/png;base64,") == len(report.figures)
    assert f"{STOPPED}: incomplete: stopped in phase questionnaire" in page
    assert "Table II" in page and "Table III" in page and "Table IV" in page


def test_a_database_of_another_schema_version_is_named_and_the_rest_reported(study, tmp_path):
    copy = tmp_path / "study"
    copy.mkdir()
    for code in ("P01", "P03"):
        shutil.copy(study / f"{code}.sqlite", copy)
    with sqlite3.connect(copy / "P03.sqlite") as conn:
        conn.execute("PRAGMA user_version = 7")
    report = build_report(copy, tmp_path / "out")
    (path, reason), = report.unreadable.items()
    assert path.endswith("P03.sqlite") and "schema version 7" in reason
    assert list(csv(report, "sessions").index) == ["P01"]
    page = report.html.read_text()
    assert f"not read, left out: {path} has schema version 7" in page


def test_empty_and_unreadable_study_folders_are_errors(tmp_path, capsys):
    study = tmp_path / "study"
    study.mkdir()
    with pytest.raises(StoreError, match="holds no participant database"):
        build_report(study, tmp_path / "out")
    (study / "X1.sqlite").write_bytes(b"not a database at all" * 100)
    with pytest.raises(StoreError, match=r"no readable participant database.*not a readable SQLite"):
        build_report(study, tmp_path / "out")
    assert main(["report", str(tmp_path / "nothing"), "--out", str(tmp_path / "o")]) == 2
    assert "holds no participant database" in capsys.readouterr().err


def test_report_command_with_benchmark(study, tmp_path, capsys):
    """Slow (~20 s in a loaded full run): a small `benchmark-pl` (two trials of preference learning)
    before the report that cites it."""
    bench = tmp_path / "bench"
    assert main(["benchmark-pl", "--trials", "2", "--queries", "6", "--initial", "3", "--q", "2",
                 "--out", str(bench), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["report", str(study), "--out", str(tmp_path / "r"), "--benchmark", str(bench),
                 "--include-simulated"]) == 0
    captured = capsys.readouterr()
    assert "validation score > 50 %" in captured.out and "Sign test, N=" in captured.out
    assert f"incomplete sessions, left out of the tests: {STOPPED}" in captured.err
    assert (tmp_path / "r" / "figures" / "fig3.png").exists()
    assert (tmp_path / "r" / "figures" / "fig3.svg").exists()
    assert main(["report", str(study), "--out", str(tmp_path / "r2"), "--benchmark",
                 str(tmp_path)]) == 2
    assert "holds no benchmark-pl condition" in capsys.readouterr().err


@pytest.mark.parametrize("inside", [".", "report", "report/deeper"])
def test_a_report_into_the_study_folder_is_refused_and_writes_nothing(study, capsys, inside):
    """``report --out`` pointing into the study folder wrote report.html, tables/ and figures/
    among the participants' databases (issue 45): as export, a report never writes into a study
    folder."""
    before = contents(study)
    out = study / inside
    assert main(["report", str(study), "--out", str(out)]) == 2
    assert (f"handover report: error: --out {out} is inside the study folder {study}: a report "
            "never writes into a study folder") in capsys.readouterr().err
    assert contents(study) == before
