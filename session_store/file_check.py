"""A participant file judged by its contents, read only: what it holds decides, not its name.

Nothing here writes to the study folder: the file is opened with SQLite's ``mode=ro``, or with
``immutable=1`` where SQLite would otherwise create the ``-wal`` and ``-shm`` files a WAL database
needs and no ``-wal`` file holds transactions: in a read-only folder (where it cannot), and for a
file an earlier version's writer left in WAL mode while no writer holds it. A file is refused,
unchanged, when it is empty or holds no session, is not one of ours, or holds another participant's
session than its name says (a copy or a renamed file). Write failures (a full disk) become one message too.
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator
from pathlib import Path

from session_store.errors import (
    CorruptStoreError,
    EmptyStoreError,
    LockRefused,
    LockUnreadable,
    MisnamedStoreError,
    SchemaVersionError,
    StoreWriteError,
)
from session_store.lock import holder_of

#: SQLite's result codes of a write that failed for want of room, a working disk or the right to
#: write: what happened, and what to do before resuming.
WRITE_FAILURES = {
    "SQLITE_FULL": ("the disk is full", "Free the disk"),
    "SQLITE_IOERR": ("the disk failed (I/O error)", "Check the disk (its cable, its mount, the "
                     "system log)"),
    "SQLITE_READONLY": ("the file or its folder is read-only", "Make the file and its folder "
                        "writable by this user (their owner and mode; not a read-only mount)"),
}


#: Bytes 18-19 of a database file's header (its read and write format versions) in WAL mode.
WAL_MODE = b"\x02\x02"


def _sidecar(path: Path, suffix: str) -> Path:
    return path.with_name(path.name + suffix)


def _wal_holds_transactions(path: Path) -> bool:
    """A ``-wal`` file beside ``path`` holds transactions that the main file does not have yet."""
    wal = _sidecar(path, "-wal")
    return wal.exists() and wal.stat().st_size > 0


def _closed_in_wal_mode(path: Path) -> bool:
    """``path`` is a database an earlier version's writer left in WAL mode, closed: its header says
    WAL, no ``-wal`` file holds transactions and no writer holds its lock. SQLite would give a
    read-only connection to it a ``-wal`` and a ``-shm`` that the reader cannot remove."""
    try:
        with open(path, "rb") as file:
            header = file.read(20)
    except OSError:
        return False
    if header[18:20] != WAL_MODE or _wal_holds_transactions(path):
        return False
    try:
        return holder_of(path) is None
    except LockUnreadable:  # another user's: with no transaction in a -wal, the file holds them all
        return True
    except LockRefused:  # a lock file that is not one (a symlink): whoever writes, read as before
        return False


def _immutable(path: Path, uri: str) -> sqlite3.Connection:
    """A connection that reads the main file only (nothing else is asked of the folder)."""
    conn = sqlite3.connect(f"{uri}?immutable=1", uri=True)
    try:
        conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
    except sqlite3.DatabaseError as exc:
        conn.close()
        raise CorruptStoreError(f"{path} is not a readable SQLite database: {exc}") from exc
    return conn


def connect_read_only(path: Path) -> sqlite3.Connection:
    """A read-only connection to ``path`` that has been seen to open (raises CorruptStoreError or
    StoreError saying why it cannot be read)."""
    uri = Path(path).resolve().as_uri()
    if _closed_in_wal_mode(path):
        return _immutable(path, uri)
    try:
        conn = sqlite3.connect(f"{uri}?mode=ro", uri=True)
    except sqlite3.Error as exc:
        raise CorruptStoreError(f"{path} cannot be opened: {exc}") from exc
    try:
        conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
        return conn
    except sqlite3.DatabaseError as exc:
        conn.close()
        if getattr(exc, "sqlite_errorname", "") != "SQLITE_CANTOPEN":
            raise CorruptStoreError(f"{path} is not a readable SQLite database: {exc}") from exc
    if _wal_holds_transactions(path):
        wal, shm = _sidecar(path, "-wal"), _sidecar(path, "-shm")
        raise CorruptStoreError(
            f"{path} cannot be read here: its latest transactions are in {wal.name}, which SQLite "
            f"reads only with {shm.name}, and this folder is read-only; copy the study folder to a "
            "writable place and run the command on the copy")
    return _immutable(path, uri)  # a read-only folder, no WAL to read


def stored_code(conn: sqlite3.Connection, path: Path) -> str:
    """The participant code stored in the open file ``path``; refuses a file that holds no
    session or is not a handover-lab database."""
    try:
        tables = [row[0] for row in conn.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        if not tables:
            raise EmptyStoreError(
                f"{path} holds no session ({Path(path).stat().st_size} bytes, no tables): a "
                "creation stopped before its first write, a failed copy or a file truncated by a "
                "crash. It was left as it is; if this participant's session is nowhere else, "
                "delete the file to start it afresh")
        if "participant" not in tables:
            raise SchemaVersionError(f"{path} is an SQLite file but not a handover-lab database "
                                     f"(tables {tables[:5]})")
        rows = conn.execute("SELECT code FROM participant").fetchall()
    except sqlite3.DatabaseError as exc:
        raise CorruptStoreError(f"{path} is not a readable SQLite database: {exc}") from exc
    if len(rows) != 1:
        raise EmptyStoreError(f"{path} holds no session: its creation never committed "
                              f"({len(rows)} participant rows)")
    return rows[0][0]


def check_participant_file(path: Path, code: str) -> None:
    """Refuse ``path`` unless it holds participant ``code``'s session (nothing is written)."""
    with contextlib.closing(connect_read_only(path)) as conn:
        stored = stored_code(conn, path)
    if stored != code:
        raise MisnamedStoreError(
            f"{path} holds participant {stored!r}'s session, not {code!r}'s: a copy or a renamed "
            f"file. It was left as it is and is not read as {code!r}; rename it back to "
            f"{stored}{Path(path).suffix} or remove the copy")


def write_failure(exc: sqlite3.Error, path: Path) -> StoreWriteError | None:
    """The StoreWriteError that ``exc`` means for a write to ``path``, or None if it is not a
    write failure (a full disk, an I/O error, a read-only file): what happened and what to do."""
    name = getattr(exc, "sqlite_errorname", "") or ""
    cause = next((text for prefix, text in WRITE_FAILURES.items() if name.startswith(prefix)), None)
    if cause is None:
        return None
    why, remedy = cause
    return StoreWriteError(
        f"could not write {path}: {why} ({exc}). This action was not stored; everything stored "
        f"before it is kept. {remedy}, then resume the session")


@contextlib.contextmanager
def explained_writes(path: Path) -> Iterator[None]:
    """Turn SQLite's write failures inside the block into StoreWriteError naming ``path``."""
    try:
        yield
    except sqlite3.Error as exc:
        failure = write_failure(exc, path)
        if failure is None:
            raise
        raise failure from exc
