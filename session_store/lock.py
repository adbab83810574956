"""One writer per participant: an exclusive OS-level lock beside the database.

``<code>.sqlite.lock`` is locked with ``flock(LOCK_EX)`` by whichever process writes the participant
(``serve`` with the participant open, ``run-session``, anything that opens the store for writing).
The kernel drops the lock when the process ends, however it ends (SIGKILL, power cut of the
process), so a stale lock never blocks: the file may still name the last holder, but nobody holds
it. The holder (pid, host, command, since) is written into the file, so a refused writer can say
who holds it. Readers (export, report, Datasette, ``doctor``) never take it.

Within a process a lock can be taken early (:func:`reserve`: the command line, before its slow
imports, so that a second writer is refused at once) and then claimed by the store that writes
(:func:`claim`); a second claim in the same process is refused like another process would be.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import socket
import sys
import time
from collections.abc import Iterator, Sequence
from datetime import UTC, datetime
from pathlib import Path

from pydantic import BaseModel, ConfigDict, ValidationError

from session_store.errors import LockRefused, LockUnreadable, ParticipantLocked, StudyNotWritable

#: A writer retries this long before it reports the lock as held: a reader's probe (doctor) holds a
#: shared lock for microseconds and must never refuse a writer.
RETRY_S = 0.05


class Holder(BaseModel):
    """Who holds (or last held) a participant's lock."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    pid: int
    host: str
    command: str
    since: str

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host} since {self.since}: {self.command}"


#: The lock file is its owner's only: it names the holder's command line.
LOCK_MODE = 0o600


def _open_lock(path: Path, flags: int) -> int:
    """Open a lock file, never through a symbolic link: a link planted in the study folder would
    have the lock's holder record written over the file it points to."""
    try:
        return os.open(path, flags | os.O_NOFOLLOW | os.O_CLOEXEC, LOCK_MODE)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise LockRefused(f"{path} is a symbolic link, not a lock file; refused before writing "
                              "anything (remove the link)") from None
        raise


def _open_for_writing(path: Path) -> int:
    """Open (or create) a lock file that a writer holds; a folder this process cannot write (a
    read-only mount, another user's study) is refused in plain words, naming the folder."""
    try:
        return _open_lock(path, os.O_RDWR | os.O_CREAT)
    except OSError as exc:
        if exc.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise
        raise StudyNotWritable(
            f"cannot write to the study folder {path.parent} ({exc.strerror}): a writer keeps its "
            f"lock file {path.name} there. Run as the folder's owner, or copy the study to a "
            "folder you can write; reading it (export, report, doctor) needs no lock") from None


def lock_path(database: Path) -> Path:
    """The lock file of a participant database: ``P09.sqlite`` → ``P09.sqlite.lock``."""
    database = Path(database)
    return database.with_name(database.name + ".lock")


#: Options whose value is a secret: the lock file and every message that names the holder show
#: the command line without it.
SECRET_OPTIONS = ("--token",)


def redacted(argv: Sequence[str]) -> list[str]:
    """``argv`` with the value of every :data:`SECRET_OPTIONS` option (``--token X``,
    ``--token=X``) replaced by ``***``."""
    shown: list[str] = []
    for argument in argv:
        option = argument.split("=", 1)[0]
        if shown and shown[-1] in SECRET_OPTIONS:
            argument = "***"
        elif option in SECRET_OPTIONS and "=" in argument:
            argument = f"{option}=***"
        shown.append(argument)
    return shown


def _this_holder(argv: Sequence[str] | None) -> Holder:
    """This process as the holder; its command line is ``argv`` (default: its own), redacted."""
    argv = argv or [Path(sys.argv[0]).name, *sys.argv[1:]]
    shown = " ".join(redacted(argv))
    return Holder(pid=os.getpid(), host=socket.gethostname(), command=shown[:300],
                  since=datetime.now(UTC).isoformat(timespec="seconds"))


def _read_holder(fd: int) -> Holder | None:
    try:
        text = os.pread(fd, 4096, 0).decode()
        return Holder.model_validate_json(text) if text.strip() else None
    except (OSError, UnicodeDecodeError, ValidationError):
        return None


def _refusal(database: Path, holder: Holder | None) -> ParticipantLocked:
    who = holder.describe() if holder is not None else "another process (not yet recorded)"
    return ParticipantLocked(
        f"participant {Path(database).stem!r} is open for writing by {who}; refused before writing "
        f"anything. Close it there first (a killed process releases it by itself; {lock_path(database)}"
        " is only a lock)")


class WriterLock:
    """The held lock of one participant database (see the module's docstring)."""

    def __init__(self, database: Path, fd: int, holder: Holder) -> None:
        self.database, self._fd, self.holder = Path(database), fd, holder
        self.reserved = False
        self.claimed = False

    @classmethod
    def acquire(cls, database: Path, argv: Sequence[str] | None = None) -> WriterLock:
        """Take the lock (refusing with the holder named if another writer has it) and record
        this process as its holder."""
        path = lock_path(database)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = _open_for_writing(path)
        os.fchmod(fd, LOCK_MODE)  # a lock file of an earlier version may be 644
        deadline = time.monotonic() + RETRY_S
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    holder = _read_holder(fd)
                    os.close(fd)
                    raise _refusal(database, holder) from None
                time.sleep(0.01)
        holder = _this_holder(argv)
        os.ftruncate(fd, 0)
        os.pwrite(fd, holder.model_dump_json().encode(), 0)
        return cls(database, fd, holder)

    def release(self) -> None:
        """Give the lock up (the file stays: deleting it would race with the next writer)."""
        if self._fd < 0:
            return
        _HELD.pop(self.database.resolve(), None)
        with contextlib.suppress(OSError):
            fcntl.flock(self._fd, fcntl.LOCK_UN)
        os.close(self._fd)
        self._fd = -1

    @property
    def held(self) -> bool:
        return self._fd >= 0


#: The locks this process holds, by database path.
_HELD: dict[Path, WriterLock] = {}


def reserve(database: Path, argv: Sequence[str] | None = None) -> WriterLock:
    """Take the lock early for a writer this process will open (kept until released or exit)."""
    key = Path(database).resolve()
    lock = _HELD.get(key)
    if lock is None:
        lock = _HELD[key] = WriterLock.acquire(database, argv)
    lock.reserved = True
    return lock


def claim(database: Path) -> WriterLock:
    """The lock for a store that writes ``database``: the one this process reserved, else a new
    one. Refused if another process holds it, or another store of this process claimed it."""
    key = Path(database).resolve()
    lock = _HELD.get(key)
    if lock is None:
        lock = _HELD[key] = WriterLock.acquire(database)
    elif lock.claimed:
        raise _refusal(database, lock.holder)
    lock.claimed = True
    return lock


def unclaim(lock: WriterLock) -> None:
    """The store is closed: release the lock unless the process reserved it for later."""
    lock.claimed = False
    if not lock.reserved:
        lock.release()


#: The study folder's lock for creating participants (see :func:`creating_participant`).
CREATION_LOCK = ".new-participant.lock"


@contextlib.contextmanager
def creating_participant(study_dir: Path) -> Iterator[None]:
    """Held while a new participant's seed is checked and its session created, so that the check
    and the creation are one step for the study folder: two creations (two processes, or two in
    one ``serve``) run one after the other, and the second sees the first's seed. Waits for the
    creation in progress, which its rig's connect timeouts bound; the kernel drops the lock of a
    process that dies."""
    study_dir = Path(study_dir)
    study_dir.mkdir(parents=True, exist_ok=True)
    fd = _open_for_writing(study_dir / CREATION_LOCK)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing the only descriptor releases the lock


def holder_of(database: Path) -> Holder | None:
    """Who holds the writer's lock of ``database`` now (None: nobody). Never blocks a writer: a
    shared lock is tried for an instant and a writer retries for :data:`RETRY_S`."""
    path = lock_path(database)
    key = Path(database).resolve()
    if key in _HELD:
        return _HELD[key].holder
    try:
        fd = _open_lock(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    except PermissionError:
        raise LockUnreadable(f"{path.name} is not readable by this user (another user's study?): "
                             "whether a writer has the participant open cannot be told") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_holder(fd) or Holder(pid=0, host="?", command="(not yet recorded)",
                                              since="?")
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
