"""One writer per participant: a second writer — in this process or another — is refused before it
writes, with the holder named; readers keep working; a killed holder never blocks."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest
from support.engine import new_engine

from app.cli import reserve_participant
from app.protocol.engine import SessionEngine
from session_store.errors import LockRefused, ParticipantLocked
from session_store.export import load_study
from session_store.lock import LOCK_MODE, holder_of, lock_path, redacted
from session_store.store import ParticipantStore

#: A child that holds the participant's writer lock until it is killed: it waits for stdin to close
#: (never, until the test kills it; and if the test process itself dies, the pipe closes and the
#: child ends instead of holding the lock for a fixed time).
HOLD = ("import sys; from session_store.store import ParticipantStore; "
        "store = ParticipantStore.open_for_writing(sys.argv[1], 'S01'); print('held', flush=True); "
        "sys.stdin.read()")


@pytest.fixture
def study(tmp_path):
    new_engine(tmp_path).close()
    return tmp_path


@contextlib.contextmanager
def held_in_child(study, *arguments: str) -> Iterator[subprocess.Popen]:
    """A child process holding S01's writer lock (``arguments``: more of its command line); killed
    (SIGKILL, by its own pid) and reaped on leaving, whatever happened inside."""
    child = subprocess.Popen([sys.executable, "-c", HOLD, str(study), *arguments], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        said = child.stdout.readline().strip()  # blocks until it holds the lock, or has ended
        assert said == "held", f"the holder said {said!r} (exit code {child.poll()})"
        yield child
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()  # reaped: its returncode is set, its lock released by the kernel
        child.stdin.close()
        child.stdout.close()


def test_a_second_writer_in_this_process_is_refused_and_writes_nothing(study):
    engine = SessionEngine.resume(study, "S01")
    try:
        before = engine.store.counts()
        with pytest.raises(ParticipantLocked, match=rf"open for writing by pid {os.getpid()} "):
            SessionEngine.resume(study, "S01")
        assert engine.store.counts() == before
        reader = ParticipantStore.open(study, "S01")  # readers need no lock
        assert reader.counts() == before
        reader.close()
    finally:
        engine.close()
    SessionEngine.resume(study, "S01").close()  # released on close


@pytest.mark.soak
def test_another_process_is_named_readers_work_and_its_kill_frees_the_participant(study):
    with held_in_child(study) as child:
        holder = holder_of(study / "S01.sqlite")
        assert holder is not None and holder.pid == child.pid
        events = ParticipantStore.open(study, "S01").counts()["events"]
        with pytest.raises(ParticipantLocked) as refused:
            SessionEngine.resume(study, "S01")
        assert f"pid {child.pid} on " in str(refused.value) and "-c" in str(refused.value)
        tables = load_study(study, ("participants", "events")).tables  # export reads meanwhile
        assert len(tables["events"]) == events
        with pytest.raises(ParticipantLocked):
            ParticipantStore.open_for_writing(study, "S01")
    assert child.returncode == -signal.SIGKILL
    # The lock file still names the killed process, but nobody holds the lock.
    assert json.loads(lock_path(study / "S01.sqlite").read_text())["pid"] == child.pid
    assert holder_of(study / "S01.sqlite") is None
    engine = SessionEngine.resume(study, "S01")
    assert engine.store.counts()["events"] == events + 1  # its own session_resumed
    engine.close()


def test_a_lock_file_that_is_a_symlink_is_refused_and_its_target_kept(study):
    """Before, the link was followed and the holder record written over its target."""
    victim = study / "victim.txt"
    victim.write_text("not a lock")
    lock = lock_path(study / "S01.sqlite")
    lock.unlink(missing_ok=True)
    lock.symlink_to(victim)
    events = ParticipantStore.open(study, "S01").counts()["events"]
    for attempt in (lambda: SessionEngine.resume(study, "S01"), lambda: holder_of(study / "S01.sqlite")):
        with pytest.raises(LockRefused, match=r"S01\.sqlite\.lock is a symbolic link"):
            attempt()
    assert victim.read_text() == "not a lock"
    assert ParticipantStore.open(study, "S01").counts()["events"] == events


@pytest.mark.parametrize("argv", [["serve", "--token", "s3cret", "--participant", "P1"],
                                  ["serve", "--token=s3cret", "--participant", "P1"]])
def test_a_token_on_the_command_line_is_never_shown(argv):
    shown = redacted(argv)
    assert "s3cret" not in " ".join(shown) and shown[-2:] == ["--participant", "P1"]


def test_the_lock_file_is_its_owners_only_and_names_no_token(study):
    """Before, the lock file was 644, kept after exit, and held the whole command line with the
    dashboard token; refusals and ``doctor`` printed it."""
    lock = lock_path(study / "S01.sqlite")
    os.chmod(lock, 0o644)  # as an earlier version left it
    with held_in_child(study, "--token", "s3cret") as child:
        assert lock.stat().st_mode & 0o777 == LOCK_MODE
        assert "s3cret" not in lock.read_text() and "--token ***" in lock.read_text()
        with pytest.raises(ParticipantLocked) as refused:
            SessionEngine.resume(study, "S01")
        assert f"pid {child.pid}" in str(refused.value) and "s3cret" not in str(refused.value)


def test_a_writer_reserved_from_its_command_line_names_no_token(study):
    """``serve --participant S01 --token …`` takes the lock from its command line, before its slow
    imports: that command line is redacted too."""
    lock = reserve_participant(["serve", "--study", str(study), "--participant", "S01",
                                "--token", "s3cret"])
    try:
        text = lock_path(study / "S01.sqlite").read_text()
        assert "--token ***" in text and "s3cret" not in text
    finally:
        lock.release()
