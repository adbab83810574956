"""The exception hierarchy of ``session_store``: every message says what was refused and why."""

from __future__ import annotations


class StoreError(Exception):
    """Base of every error raised by ``session_store``."""


class UnsafeParticipantCode(StoreError, ValueError):
    """A participant code that cannot be a file name (path parts, empty, too long, odd characters)."""


class SchemaVersionError(StoreError):
    """The database was written by a newer handover-lab (or is not one of ours)."""


class CorruptStoreError(StoreError):
    """The file is not a readable SQLite database, or its integrity check fails."""


class EmptyStoreError(CorruptStoreError):
    """The file holds no session: empty, no tables, or a creation that never committed."""


class MisnamedStoreError(StoreError):
    """The file holds another participant's session than its name says (a copy or a rename)."""


class StoreWriteError(StoreError):
    """The database could not be written (disk full, I/O error, read-only); nothing of the write
    was stored, everything stored before it is kept."""


class ParticipantLocked(StoreError):
    """Another writer holds the participant's database (names the holder); nothing was written."""


class LockRefused(StoreError):
    """A participant's lock file is not one (a symbolic link): refused before anything is written."""


class LockUnreadable(LockRefused):
    """A participant's lock file cannot be read by this user: whether a writer holds it is unknown
    (readers go on without it)."""


class StudyNotWritable(StoreError):
    """The study folder cannot be written by this process (read-only, another user's): a writer is
    refused before anything is written."""
