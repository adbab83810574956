"""Every failure of the study's storage is a message, not a traceback, and loses nothing (issue 15):
an empty .sqlite is named and left as it is; a disk that fills up mid-session stops the session with
a message, keeps everything stored before, and the session resumes once there is room."""

from __future__ import annotations

import contextlib
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from support.engine import SHORT_PROTOCOL
from support.study import grow, small_disk

from app.cli import main
from session_store.errors import EmptyStoreError
from session_store.store import ParticipantStore


def run_session(study: Path, *extra: str) -> list[str]:
    return ["run-session", "--study", str(study), "--participant", "P01", "--auto",
            "--no-progress", *extra]


def test_an_empty_file_is_named_and_left_as_it_is(tmp_path, capsys):
    study = tmp_path / "study"
    study.mkdir()
    empty = study / "P01.sqlite"
    empty.touch()
    mtime = empty.stat().st_mtime_ns
    for extra in (["--resume"], ["--scenario", "perturbed"], ["--resume", "--scenario", "perturbed"]):
        assert main(run_session(study, *extra)) == 2, extra
        err = capsys.readouterr().err
        assert f"{empty} holds no session (0 bytes, no tables)" in err, extra
        assert "It was left as it is" in err
    with pytest.raises(EmptyStoreError):
        ParticipantStore.open(study, "P01")
    assert main(["report", str(study), "--out", str(tmp_path / "report")]) == 2
    assert "holds no session (0 bytes" in capsys.readouterr().err
    assert (empty.stat().st_size, empty.stat().st_mtime_ns) == (0, mtime)
    # the writer's lock file (session_store/lock.py) stays, as flock lock files do: it holds no data
    assert sorted(os.listdir(study)) == ["P01.sqlite", "P01.sqlite.lock"]


def stored(path: Path) -> list[tuple]:
    with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn:
        return conn.execute("SELECT seq, at, actor, kind, payload FROM events ORDER BY seq").fetchall()


@pytest.mark.slow
def test_a_full_disk_stops_the_session_with_a_message_and_loses_nothing(tmp_path):
    """Slow: two ``run-session`` processes, each starting its learner (torch, a BoTorch fit per
    batch): the first runs until the 2 MB disk is full, the second resumes and ends the session."""
    config = tmp_path / "lab.toml"
    config.write_text("[protocol]\n" + "".join(f"{k} = {v}\n" for k, v in SHORT_PROTOCOL.items()))
    command = [sys.executable, "-m", "app.cli", *run_session(tmp_path / "disk" / "study"),
               "--config", str(config)]
    with small_disk(tmp_path / "disk", megabytes=2) as disk:
        full = subprocess.run([*command, "--scenario", "perturbed", "--json"], capture_output=True,
                              text=True, timeout=600)
        assert full.returncode == 2, full.stderr[-3000:]
        assert "Traceback" not in full.stderr, full.stderr[-3000:]
        assert "handover run-session: error: the session stopped: could not write" in full.stderr
        assert "the disk is full" in full.stderr and "resume the session" in full.stderr
        database = disk / "study" / "P01.sqlite"
        before = stored(database)
        assert len(before) > 10  # it stopped in the middle: created, trials stored before
        assert before[-1][3] != "answer_given"

        grow(disk, megabytes=64)  # the experimenter freed the disk
        resumed = subprocess.run([*command, "--resume", "--json"], capture_output=True, text=True,
                                 timeout=600)
        assert resumed.returncode == 0, resumed.stderr[-3000:]
        after = stored(database)
    assert after[:len(before)] == before  # nothing stored was lost or changed
    assert after[len(before)][3] == "session_resumed"
    assert '"completed": 9' in resumed.stdout


@pytest.mark.parametrize("target", ["file", "full"])
def test_an_export_that_cannot_write_is_a_message(tmp_path, capsys, target):
    from support.engine import new_engine

    study = tmp_path / "study"
    new_engine(study, "P01").close()
    if target == "file":
        out = tmp_path / "a-file"
        out.write_text("not a folder")
        expected = f"{out}/sqlite: Not a directory"
        assert main(["export", str(study), "--out", str(out)]) == 2
        assert expected in capsys.readouterr().err
        return
    with small_disk(tmp_path / "disk", megabytes=1) as disk:
        (disk / "ballast").write_bytes(b"\0" * (1024 * 1024 - 64 * 1024))
        assert main(["export", str(study), "--out", str(disk / "out")]) == 2
    err = capsys.readouterr().err
    assert "handover export: error:" in err
    assert "the disk is full" in err or "No space left on device" in err


def test_a_read_only_database_is_not_told_to_free_the_disk(tmp_path):
    """A write refused by a read-only database said "Free the disk, then resume the session"
    (issue 45, item 7): each cause has its own advice. (SQLite's own refusals, on a connection
    opened read-only and on a full disk's result code.)"""
    from support.engine import new_engine

    from session_store.file_check import write_failure

    study = tmp_path / "study"
    new_engine(study, "P01").close()
    path = study / "P01.sqlite"
    with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn, \
            pytest.raises(sqlite3.OperationalError) as refused:
        conn.execute("DELETE FROM events")
    failure = write_failure(refused.value, path)
    assert failure is not None
    assert "the file or its folder is read-only" in str(failure)
    assert "Free the disk" not in str(failure)
    assert str(failure).endswith(". Make the file and its folder writable by this user (their owner "
                                 "and mode; not a read-only mount), then resume the session")
    full = sqlite3.OperationalError("database or disk is full")
    full.sqlite_errorname = "SQLITE_FULL"  # as SQLite sets it on a full disk
    assert str(write_failure(full, path)).endswith("Free the disk, then resume the session")
