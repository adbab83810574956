"""``handover doctor`` names each problem of a study folder, and a log that breaks the protocol is
reported as such (event number, what is wrong) — never as a KeyError."""

from __future__ import annotations

import json
import shutil
import sqlite3
from contextlib import closing
from pathlib import Path

import pytest
from support.engine import drive_until, new_engine

from app.cli import main
from app.protocol.engine import SessionEngine
from app.protocol.errors import EventLogError
from app.protocol.state import Step


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
