"""``handover doctor`` names each problem of a study folder, and a log that breaks the protocol is
reported as such (event number, what is wrong) — never as a KeyError."""

from __future__ import annotations

import json
import shutil
import sqlite3
from contextlib import closing
from pathlib import Path

import pandas as pd
import pytest
from support.engine import closed_session, drive_until, new_engine

from app.cli import main
from app.protocol.engine import SessionEngine
from app.protocol.errors import EventLogError
from app.protocol.state import Step
from session_store.export import read_table


def _sql(path: Path, *statements: str) -> None:
    """Change a file as another program would, leaving no WAL behind."""
    with closing(sqlite3.connect(path)) as conn, conn:
        for statement in statements:
            conn.execute(statement)
    with closing(sqlite3.connect(path)) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")


def _double_a_completion(path: Path) -> int:
    """What two writers left in the issue: the interaction that waits for its placement is
    completed a second time, by another trial. Returns the number of the first bad event."""
    with closing(sqlite3.connect(path)) as conn, conn:
        (trial,) = conn.execute("SELECT * FROM trials ORDER BY trial_index DESC LIMIT 1").fetchall()
        names = [d[0] for d in conn.execute("SELECT * FROM trials").description]
        row = dict(zip(names, trial, strict=True))
        twin = {**row, "trial_index": row["trial_index"] + 1, "attempt": row["attempt"] + 1}
        conn.execute(f"INSERT INTO trials ({', '.join(twin)}) VALUES "
                     f"({', '.join('?' for _ in twin)})", list(twin.values()))
        seq = conn.execute("SELECT max(seq) FROM events").fetchone()[0] + 1
        for kind, payload in (
                ("trial_started", {"trial_index": twin["trial_index"],
                                   "interaction": twin["interaction"], "attempt": twin["attempt"]}),
                ("trial_ended", {"trial_index": twin["trial_index"], "outcome": "completed",
                                 "reason": None})):
            conn.execute("INSERT INTO events (at, actor, kind, payload) VALUES (?, ?, ?, ?)",
                         ["2026-01-01T00:00:00+00:00", "system", kind, json.dumps(payload)])
    _sql(path)
    return seq


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> Path:
    study = tmp_path_factory.mktemp("good")
    engine = new_engine(study, "G01")
    drive_until(engine, Step.PLACE)
    engine.place(position=0.4)
    drive_until(engine, Step.PLACE)  # interaction 2 completed, waiting for its placement
    engine.close()
    return study / "G01.sqlite"


def test_a_doubled_completion_is_an_event_log_error_naming_the_event(good, tmp_path):
    shutil.copy(good, tmp_path / "D01.sqlite")
    _sql(tmp_path / "D01.sqlite", "UPDATE participant SET code = 'D01'")
    seq = _double_a_completion(tmp_path / "D01.sqlite")
    with pytest.raises(EventLogError) as error:
        SessionEngine.resume(tmp_path, "D01")
    assert error.value.seq == seq and error.value.kind == "trial_started"
    assert f"event {seq} (trial_started): trial 3 starts while the session waits for 'place'" \
        in str(error.value)
    with sqlite3.connect(tmp_path / "D01.sqlite") as conn:  # the refused resume wrote nothing
        assert conn.execute("SELECT count(*) FROM events WHERE kind = 'session_resumed'"
                            ).fetchone()[0] == 0


def test_doctor_names_each_problem_and_exits_non_zero(good, tmp_path, capsys):
    study = tmp_path / "study"
    study.mkdir()
    shutil.copy(good, study / "G01.sqlite")
    for code in ("N01", "D01", "C01"):
        shutil.copy(good, study / f"{code}.sqlite")
        _sql(study / f"{code}.sqlite", f"UPDATE participant SET code = '{code}'")
    _sql(study / "N01.sqlite", "PRAGMA user_version = 9")
    _double_a_completion(study / "D01.sqlite")
    data = bytearray((study / "C01.sqlite").read_bytes())
    data[4096 * 2: 4096 * 6] = b"\xff" * (4096 * 4)  # pages of the tables overwritten
    (study / "C01.sqlite").write_bytes(bytes(data))
    (study / "E01.sqlite").write_bytes(b"")
    shutil.copy(good, study / "X01.sqlite")  # a copy under another name
    before = {p.name: p.read_bytes() for p in study.glob("*.sqlite")}

    assert main(["doctor", str(study)]) == 1
    out = capsys.readouterr().out
    blocks = {name: out.split(f"{name}: ")[1].split(".sqlite: ")[0]
              for name in ("G01.sqlite", "N01.sqlite", "D01.sqlite", "C01.sqlite", "E01.sqlite",
                           "X01.sqlite")}
    assert blocks["G01.sqlite"].startswith("OK")
    assert "2 of 9 interactions completed, waiting for 'place'" in blocks["G01.sqlite"]
    assert blocks["N01.sqlite"].startswith("BAD") and "schema version 9 is newer" in blocks["N01.sqlite"]
    assert blocks["D01.sqlite"].startswith("BAD")
    assert "interaction completed by more than one trial: 2 (trials 2, 3)" in blocks["D01.sqlite"]
    assert "event log breaks the protocol: event" in blocks["D01.sqlite"]
    assert blocks["C01.sqlite"].startswith("BAD") and ("integrity" in blocks["C01.sqlite"]
                                                       or "not a readable" in blocks["C01.sqlite"])
    assert blocks["E01.sqlite"].startswith("BAD") and "empty file (0 bytes)" in blocks["E01.sqlite"]
    assert blocks["X01.sqlite"].startswith("BAD") and "holds participant 'G01'" in blocks["X01.sqlite"]
    assert "6 files: 1 OK, 5 bad" in out
    assert {p.name: p.read_bytes() for p in study.glob("*.sqlite")} == before  # read-only


def test_doctor_names_the_writer_of_a_session_in_progress(good, tmp_path, capsys):
    shutil.copy(good, tmp_path / "G01.sqlite")
    engine = SessionEngine.resume(tmp_path, "G01")
    try:
        assert main(["doctor", str(tmp_path)]) == 0
    finally:
        engine.close()
    out = capsys.readouterr().out
    assert "G01.sqlite: OK" in out and "open for writing now: pid" in out


@pytest.fixture(scope="module")
def whole(tmp_path_factory) -> Path:
    """A whole short session: placements, comparisons, the questionnaire, a validation pair."""
    return closed_session(tmp_path_factory.mktemp("whole"), "W01", seed=3)


#: Edits of a copy that the event log contradicts (issue 25, item 5: doctor said OK to 11 of 13),
#: and what doctor must say about each.
EDITS = {
    "a comparison deleted": (
        "DELETE FROM comparisons WHERE rowid = (SELECT min(rowid) FROM comparisons)",
        "is in the event log but not in the table"),
    "a comparison reversed": (
        "UPDATE comparisons SET winner = loser, loser = winner "
        "WHERE rowid = (SELECT min(rowid) FROM comparisons)", "is in the table but no event records it"),
    "a trial's θ changed": ("UPDATE trials SET theta_k = theta_k + 1 WHERE trial_index = 1",
                            "trials: trial 1 has theta_k = "),
    "a trial's outcome changed": (
        "UPDATE trials SET outcome = 'aborted', reason = 'edited' WHERE trial_index = 2",
        "trials: trial 2 has outcome = 'aborted' in the table, 'completed' in the event log"),
    "a placement moved": ("UPDATE placements SET position = 0.99 WHERE interaction = 1",
                          "placements: interaction 1 has position = 0.99 in the table"),
    "an answer changed": ("UPDATE answers SET value = value || '?' WHERE question = 'Q1'",
                          "answers: answer to Q1 has value = "),
    "a validation rating changed": (
        "UPDATE validation_ratings SET rating = CASE rating WHEN 'better' THEN 'worse' ELSE "
        "'better' END", "validation_ratings: interaction "),
    "a trial deleted": ("DELETE FROM trials WHERE trial_index = (SELECT max(trial_index) FROM "
                        "trials)", "trials: trial "),
    "the last event deleted": ("DELETE FROM events WHERE seq = (SELECT max(seq) FROM events)",
                               "is in the table but no event records it"),
    "the seed changed": ("UPDATE participant SET config = json_set(config, '$.seed', 4)",
                         "the stored plan differs from the one the session_created event records, "
                         "in seed"),
    "samples of a trial that never was": ("UPDATE samples SET trial_index = 99 WHERE trial_index = 1",
                                          "samples of a trial that is not in the trials table"),
}


@pytest.mark.parametrize("edit", EDITS)
def test_doctor_finds_every_edit_the_event_log_contradicts(whole, tmp_path, capsys, edit):
    statement, message = EDITS[edit]
    path = tmp_path / "W01.sqlite"
    shutil.copy(whole, path)
    _sql(path, statement)
    assert main(["doctor", str(tmp_path)]) == 1, capsys.readouterr().out
    out = capsys.readouterr().out
    assert "W01.sqlite: BAD" in out
    assert message in out, out


def test_doctor_says_ok_to_the_whole_session_it_checks_against(whole, tmp_path, capsys):
    shutil.copy(whole, tmp_path / "W01.sqlite")
    assert main(["doctor", str(tmp_path)]) == 0
    assert "W01.sqlite: OK" in capsys.readouterr().out


def test_export_and_report_leave_out_what_doctor_finds_bad_unless_forced(whole, tmp_path, capsys):
    """A participant whose tables contradict its event log was exported and reported as it was
    (issue 25, item 5): now both leave it out, saying why, and ``--force`` includes it with a
    warning."""
    study = tmp_path / "study"
    study.mkdir()
    shutil.copy(whole, study / "W01.sqlite")
    closed_session(study, "W02", seed=4)
    _sql(study / "W01.sqlite", "UPDATE trials SET theta_k = theta_k + 1 WHERE trial_index = 1")
    why = "W01.sqlite: handover doctor finds it BAD: trials: trial 1 has theta_k = "

    assert main(["export", str(study), "--out", str(tmp_path / "out")]) == 0
    assert f"left out {study / why}" in capsys.readouterr().err
    assert read_table(tmp_path / "out", "participants")["participant"].tolist() == ["W02"]
    assert main(["report", str(study), "--out", str(tmp_path / "report")]) == 0
    assert why in capsys.readouterr().err
    sessions = pd.read_csv(tmp_path / "report" / "tables" / "sessions.csv")
    assert sessions["participant"].tolist() == ["W02"]

    assert main(["export", str(study), "--out", str(tmp_path / "forced"), "--force"]) == 0
    assert f"warning: exported although {why}" in capsys.readouterr().err
    assert sorted(read_table(tmp_path / "forced", "participants")["participant"]) == ["W01", "W02"]
