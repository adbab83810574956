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


class RefusedAction(StoreError, ValueError):
    """An action that the protocol's current state does not allow (nothing was written)."""
