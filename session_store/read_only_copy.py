"""A participant's database opened for reading only (export, report, the recorded plan of a session
before it is resumed): a consistent in-memory copy of the file, never a write to the study folder.

The file is judged by its contents first (:mod:`session_store.file_check`), then copied with SQLite's
backup API into memory, where :class:`ParticipantStore` checks and, for an older schema version,
migrates it — so a read-only folder, an older file or a file that another process is writing are
all read as they are, and the file itself is never migrated, rewritten or locked for long.
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator
from pathlib import Path

from session_store.errors import StoreError
from session_store.file_check import check_participant_file, connect_read_only
from session_store.store import ParticipantStore, participant_path


@contextlib.contextmanager
def reading(study_dir: Path, code: str) -> Iterator[ParticipantStore]:
    """Participant ``code``'s store, read from a copy in memory (raises StoreError saying why the
    file cannot be read: missing, empty, corrupt, foreign, newer, or another participant's)."""
    path = participant_path(study_dir, code)
    if not path.exists():
        raise StoreError(f"participant {code!r} has no session in {study_dir}")
    check_participant_file(path, code)
    memory = sqlite3.connect(":memory:")
    try:
        with contextlib.closing(connect_read_only(path)) as source:
            source.backup(memory)
    except sqlite3.DatabaseError as exc:
        memory.close()
        raise StoreError(f"{path} could not be read: {exc}") from exc
    store = ParticipantStore(path, connection=memory)
    try:
        yield store
    finally:
        store.close()
