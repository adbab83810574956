"""A study folder is judged by its contents (issue 15): the code stored in a file must match its
name, a read-only folder is read as it is, one bad file never stops the export of the others, and
reading never writes to the study folder."""

from __future__ import annotations

import contextlib
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd
import pytest
from support.engine import closed_session, new_engine
from support.study import as_version_1, checkpointed, fingerprint, read_only

from app.analysis.report import build_report
from app.cli import main
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario
from session_store.errors import MisnamedStoreError
from session_store.export import DTYPES, LEFT_OUT_FILE, export_study, load_study, read_table
from session_store.store import ParticipantStore


@pytest.fixture(scope="module")
def original(tmp_path_factory) -> Path:
    """P01's whole short session and P02's first placement, cleanly closed (no -wal, no -shm)."""
    study = tmp_path_factory.mktemp("original")
    closed_session(study, "P01", seed=3)
    closed_session(study, "P02", Step.PLACE, seed=4, scenario=Scenario.PERTURBED)
    for path in study.glob("*.sqlite"):
        checkpointed(path)
    return study


@pytest.fixture
def study(original, tmp_path) -> Path:
    return Path(shutil.copytree(original, tmp_path / "study"))


def rows_per_participant(out: Path, table: str) -> dict[str, int]:
    return read_table(out, table).groupby("participant").size().to_dict()


def stored_rows(path: Path, table: str) -> int:
    with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn:
        return conn.execute(f'SELECT count(*) FROM "{table}"').fetchone()[0]


def test_a_copy_under_another_name_is_reported_not_merged(study, tmp_path, capsys):
    """Slow (~24 s in a loaded full run) as the module's first test: it pays for ``original``, a
    short session to its end and one to its first placement through the real learner."""
    copy = study / "P03.sqlite"
    shutil.copy(study / "P01.sqlite", copy)
    before = fingerprint(copy)
    out = tmp_path / "out"
    assert main(["export", str(study), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"left out {copy}: {copy} holds participant 'P01''s session, not 'P03''s" in err
    assert sorted(read_table(out, "participants")["participant"]) == ["P01", "P02"]
    assert rows_per_participant(out, "trials") == {
        code: stored_rows(study / f"{code}.sqlite", "trials") for code in ("P01", "P02")}
    assert not (out / "sqlite" / "P03.sqlite").exists()
    left_out = pd.read_csv(out / LEFT_OUT_FILE)
    assert left_out["file"].tolist() == [str(copy)]
    assert "rename it back to P01.sqlite" in left_out["reason"][0]

    report = build_report(study, tmp_path / "report")
    assert list(report.unreadable) == [str(copy)]
    assert "holds participant 'P01''s session" in report.unreadable[str(copy)]
    assert "P03" not in set(pd.read_csv(report.tables["sessions"])["participant"])

    with pytest.raises(MisnamedStoreError, match="a copy or a renamed file"):
        ParticipantStore.open(study, "P03")
    assert main(["run-session", "--study", str(study), "--participant", "P03", "--resume",
                 "--auto", "--no-progress"]) == 2
    assert "holds participant 'P01''s session, not 'P03''s" in capsys.readouterr().err
    assert fingerprint(copy) == before


def test_a_read_only_study_folder_is_exported_and_reported_as_it_is(study, tmp_path):
    """Slow (~22 s in a loaded full run): two exports and a report (its figures) of the study."""
    assert not list(study.glob("*-wal")) and not list(study.glob("*-shm"))  # closed cleanly
    writable = export_study(study, tmp_path / "from-writable")
    with read_only(study) as view:
        export = export_study(view, tmp_path / "from-read-only")
        report = build_report(view, tmp_path / "report")
    assert export.left_out == {} and report.unreadable == {}
    for table in DTYPES:
        pd.testing.assert_frame_equal(read_table(tmp_path / "from-read-only", table),
                                      read_table(tmp_path / "from-writable", table))
    assert {t: rows for t, (_, rows) in export.written.items()} == \
        {t: rows for t, (_, rows) in writable.written.items()}
    assert report.incomplete == ["P02"]


def test_a_read_only_folder_reads_the_transactions_still_in_the_wal(study, tmp_path):
    """A copy taken while a session was open: its last transactions are only in -wal."""
    live = tmp_path / "live"
    live.mkdir()
    with contextlib.closing(sqlite3.connect(study / "P01.sqlite")) as writer:
        writer.execute("PRAGMA wal_autocheckpoint = 0")
        writer.execute("INSERT INTO events (at, actor, kind, payload) VALUES "
                       "('2026-01-01T00:00:00+00:00', 'experimenter', 'paused', '{}')")
        writer.commit()
        for suffix in ("", "-wal", "-shm"):
            shutil.copy(study / f"P01.sqlite{suffix}", live / f"P01.sqlite{suffix}")
    assert (live / "P01.sqlite-wal").stat().st_size > 0
    events = stored_rows(live / "P01.sqlite", "events")
    with read_only(live) as view:
        loaded = load_study(view, ["events"])
    assert len(loaded.tables["events"]) == events
    assert loaded.tables["events"]["kind"].iloc[-1] == "paused"

    (live / "P01.sqlite-shm").unlink()  # SQLite cannot read that -wal in a read-only folder
    shutil.copy(study / "P02.sqlite", live / "P02.sqlite")
    with read_only(live) as view:
        loaded = load_study(view, ["events"], skip_unreadable=True)
    [(path, reason)] = loaded.unreadable.items()
    assert path.name == "P01.sqlite"
    assert "latest transactions are in P01.sqlite-wal" in reason
    assert "copy the study folder to a writable place" in reason
    assert set(loaded.tables["events"]["participant"]) == {"P02"}


def test_one_bad_file_never_stops_the_export_of_the_others(study, tmp_path, capsys, caplog):
    (study / "P05.sqlite").write_bytes(b"not a database at all " * 200)
    new_engine(study, "P06").close()
    with contextlib.closing(sqlite3.connect(study / "P06.sqlite")) as conn:
        conn.execute("PRAGMA user_version = 99")
    (study / "P07.sqlite").touch()
    out = tmp_path / "out"
    assert main(["export", str(study), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    reasons = pd.read_csv(out / LEFT_OUT_FILE).set_index("file")["reason"]
    assert sorted(Path(f).name for f in reasons.index) == ["P05.sqlite", "P06.sqlite", "P07.sqlite"]
    assert "is not a readable SQLite database" in reasons[str(study / "P05.sqlite")]
    assert "schema version 99" in reasons[str(study / "P06.sqlite")]
    assert "holds no session (0 bytes" in reasons[str(study / "P07.sqlite")]
    assert "3 database(s) left out" in err and err.count("warning: left out") == 3
    # said once, by the command: the export logged each as well (a second line on the terminal)
    assert [r.getMessage() for r in caplog.records if r.name == "session_store.export"] == []
    assert sorted(read_table(out, "participants")["participant"]) == ["P01", "P02"]
    assert sorted(p.name for p in (out / "sqlite").iterdir()) == ["P01.sqlite", "P02.sqlite"]
    assert (study / "P07.sqlite").stat().st_size == 0


def test_an_export_of_nothing_readable_writes_nothing(tmp_path, capsys):
    study = tmp_path / "study"
    study.mkdir()
    (study / "P05.sqlite").write_bytes(b"not a database at all " * 200)
    (study / "P07.sqlite").touch()
    out = tmp_path / "out"
    assert main(["export", str(study), "--out", str(out)]) == 2
    assert "holds no readable participant database" in capsys.readouterr().err
    assert not out.exists()


def test_export_and_report_never_write_to_the_study_folder(study, tmp_path):
    """An older file is read through a migrated copy in memory; the file stays as it was."""
    path = study / "P01.sqlite"
    as_version_1(path)
    before = fingerprint(path)
    export = export_study(study, tmp_path / "out")
    build_report(study, tmp_path / "report")
    assert export.left_out == {}
    assert fingerprint(path) == before
    with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 1
    trials = read_table(tmp_path / "out", "trials")
    assert trials.loc[trials["participant"] == "P01", "go_at"].isna().all()  # v2 columns, empty
    assert len(trials[trials["participant"] == "P01"]) == stored_rows(path, "trials")


def contents(study: Path) -> dict[str, object]:
    """Every file of the folder: a database's fingerprint, any other file's bytes."""
    return {p.name: fingerprint(p) if p.suffix == ".sqlite" else p.read_bytes()
            for p in sorted(study.iterdir())}


def read_with_every_command(study: Path, tmp_path: Path) -> None:
    assert main(["doctor", str(study)]) == 0
    assert main(["export", str(study), "--out", str(tmp_path / "out")]) == 0
    assert main(["report", str(study), "--out", str(tmp_path / "report")]) == 0


def test_doctor_export_and_report_leave_the_study_folder_as_the_writer_left_it(tmp_path):
    """Run on a study as its writer closed it, the reading commands add no file and change none
    (before, each left a -wal and a -shm beside every database: a reader of a WAL database creates
    both and cannot remove them; issue 25, item 6)."""
    study = tmp_path / "study"
    closed_session(study, "P01", Step.PLACE, seed=3)
    before = contents(study)
    assert set(before) == {"P01.sqlite", "P01.sqlite.lock"}
    read_with_every_command(study, tmp_path)
    assert contents(study) == before


def test_files_an_earlier_version_left_in_wal_mode_are_read_without_a_file_added(study, tmp_path):
    """The files as an earlier version's writer closed them (WAL mode, no -wal or -shm), in a
    writable folder: a WAL database opened read-only gets a -wal and a -shm that its reader cannot
    remove, so each reading command left two files per participant."""
    before = contents(study)
    assert set(before) == {"P01.sqlite", "P01.sqlite.lock", "P02.sqlite", "P02.sqlite.lock"}
    read_with_every_command(study, tmp_path)
    assert contents(study) == before


def test_doctor_reads_a_read_only_folder_as_export_does(study, capsys):
    """The files as an earlier version left them (WAL mode, no -wal or -shm): in a read-only
    folder doctor called them BAD while export read them (issue 25, item 6)."""
    with read_only(study) as view:
        assert main(["doctor", str(view)]) == 0
    out = capsys.readouterr().out
    assert "P01.sqlite: OK" in out and "P02.sqlite: OK" in out and "0 bad" in out


def test_a_code_that_differs_only_in_case_is_refused_before_anything_is_written(study, capsys):
    """``s01`` beside ``P01``'s ``p01``: on a case-insensitive disk the two are one file."""
    before = sorted(p.name for p in study.iterdir())
    code = main(["run-session", "--study", str(study), "--participant", "p01", "--scenario",
                 "perturbed", "--auto"])
    assert code == 2
    assert "participant code 'p01' differs only in case from 'P01'" in capsys.readouterr().err
    assert sorted(p.name for p in study.iterdir()) == before


@pytest.mark.parametrize("command", [
    ["run-session", "--participant", "P02", "--auto", "--no-progress"],
    ["serve", "--participant", "P02", "--tablet-port", "0", "--dashboard-port", "0"],
])
def test_a_writer_in_a_folder_it_cannot_write_says_so_before_anything(study, capsys, command):
    """A read-only mount (or another user's study) was an OSError traceback from the lock file."""
    with read_only(study) as view:
        before = fingerprint(view / "P02.sqlite")
        assert main([command[0], "--study", str(view), *command[1:]]) == 2
        err = capsys.readouterr().err
        assert f"cannot write to the study folder {view} (Read-only file system)" in err, err
        assert "Traceback" not in err and fingerprint(view / "P02.sqlite") == before


#: Run as another user (nobody) the readers that need no lock: what they print, or their refusal.
AS_ANOTHER_USER = """
import importlib, os, sys
from app.cli import _COMMAND_MODULES, main
for name in (*_COMMAND_MODULES, "session_store.export", "app.analysis.report", "app.protocol.doctor"):
    importlib.import_module(name)  # imported while root may
os.setgid(65534); os.setuid(65534)
sys.exit(main(sys.argv[1:]))
"""


def test_another_users_study_is_read_without_its_lock_files(study, tmp_path):
    """As another user, doctor, export and report failed for the whole folder on the 0600 lock
    file of one participant; reading needs no lock. (report reads the folder as export does, with
    the same inspection; it imports more after the user is changed than this child may read.)"""
    shared = Path(tempfile.mkdtemp(prefix="shared-study-"))  # nobody may enter it (tmp_path: no)
    try:
        shared.chmod(0o755)
        folder = Path(shutil.copytree(study, shared / "study"))
        folder.chmod(0o755)
        for path in folder.iterdir():
            path.chmod(0o600 if path.name.endswith(".lock") else 0o644)
        (folder / "P01.sqlite.lock").write_text("")  # as a writer leaves it
        out = shared / "out"
        out.mkdir(mode=0o777)
        out.chmod(0o777)
        for command in (["doctor", str(folder)], ["export", str(folder), "--out", str(out / "x")]):
            result = subprocess.run([sys.executable, "-c", AS_ANOTHER_USER, *command],
                                    capture_output=True, text=True, env={**os.environ,
                                                                          "HOME": str(out)})
            assert result.returncode == 0 and "Permission denied" not in result.stderr, \
                (command, result.stdout, result.stderr)
        assert (out / "x" / "trials.csv").exists()
    finally:
        shutil.rmtree(shared)


@pytest.mark.parametrize("command", [
    ["run-session", "--study", "{study}", "--participant", "P01", "--resume", "--auto",
     "--no-progress"],
    ["doctor", "{study}"],
    ["export", "{study}", "--out", "{out}"],
    ["report", "{study}", "--out", "{out}"],
])
def test_another_users_unreadable_study_is_named_as_such(study, command):
    """Another user's study folder (mode 700): run-session --resume ended in a PermissionError
    traceback, and doctor, export and report said it "holds no participant database", hiding the
    cause (issue 45, item 7). Each names the folder, its owner and mode, and what to do. (Each
    runs its command in a child process as another user: its imports take most of the 20-60 s.)"""
    shared = Path(tempfile.mkdtemp(prefix="private-study-"))
    try:
        shared.chmod(0o777)
        folder = Path(shutil.copytree(study, shared / "study"))
        folder.chmod(0o700)  # root's, closed to others
        args = [word.format(study=folder, out=shared / "out") for word in command]
        result = subprocess.run([sys.executable, "-c", AS_ANOTHER_USER, *args],
                                capture_output=True, text=True,
                                env={**os.environ, "HOME": str(shared)})
        assert result.returncode == 2, (result.stdout, result.stderr)
        assert "Traceback" not in result.stderr and "holds no participant" not in result.stderr
        assert (f"handover {command[0]}: error: cannot read the study folder {folder}: permission "
                "denied (it belongs to root, mode 700): run this as root, or have root give this "
                "user read access to it") in result.stderr, result.stderr
    finally:
        shutil.rmtree(shared)
