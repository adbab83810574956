"""Study folders in odd states for tests: read-only, full, older, and a fingerprint of a file that
says whether anything wrote to it."""

from __future__ import annotations

import contextlib
import hashlib
import os
import sqlite3
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from session_store.schema import V2_SAMPLE_COLUMNS, V2_TRIAL_COLUMNS


def contents(study: Path) -> list[Path]:
    """Every file and folder under ``study``, relative to it: equal before and after means nothing
    was written into it."""
    return sorted(p.relative_to(study) for p in study.rglob("*"))


def fingerprint(path: Path) -> tuple[str, int, int]:
    """The file's SHA-256, its modification time and the size of its ``-wal`` (transactions
    written beside it): equal before and after means nothing was written."""
    wal = path.with_name(path.name + "-wal")
    return (hashlib.sha256(path.read_bytes()).hexdigest(), path.stat().st_mtime_ns,
            wal.stat().st_size if wal.exists() else 0)


def checkpointed(path: Path) -> None:
    """Fold the file's WAL into it and remove ``-wal`` and ``-shm``, as a cleanly closed (or copied)
    database is."""
    with contextlib.closing(sqlite3.connect(path)) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        conn.execute("PRAGMA journal_mode=DELETE")
        conn.execute("PRAGMA journal_mode=WAL")
    for suffix in ("-wal", "-shm"):
        path.with_name(path.name + suffix).unlink(missing_ok=True)


def as_version_1(path: Path) -> None:
    """Make ``path`` what schema version 1 wrote: without the handover cycle's columns."""
    with contextlib.closing(sqlite3.connect(path)) as db:
        for table, columns in (("trials", V2_TRIAL_COLUMNS), ("samples", V2_SAMPLE_COLUMNS)):
            for column in columns:
                db.execute(f"ALTER TABLE {table} DROP COLUMN {column}")
        db.execute("PRAGMA user_version = 1")
        db.commit()
    checkpointed(path)


def _run(*command: str) -> None:
    subprocess.run(command, check=True, capture_output=True)


def _unmount(folder: Path) -> None:
    """Unmount, lazily if a file there is still open (a connection the code under test leaked)."""
    try:
        _run("umount", str(folder))
    except subprocess.CalledProcessError:
        _run("umount", "--lazy", str(folder))


@contextlib.contextmanager
def read_only(folder: Path) -> Iterator[Path]:
    """``folder`` seen read-only: as root (whom permissions do not stop) a read-only bind mount,
    otherwise the folder with its write permissions removed. Yields the read-only path."""
    if os.geteuid() != 0:
        modes = {p: p.stat().st_mode for p in [folder, *folder.iterdir()]}
        for p in modes:
            p.chmod(0o555 if p.is_dir() else 0o444)
        try:
            yield folder
        finally:
            for p, mode in modes.items():
                p.chmod(mode)
        return
    view = folder.with_name(folder.name + "-ro")
    view.mkdir()
    try:
        _run("mount", "--bind", str(folder), str(view))
    except (OSError, subprocess.CalledProcessError) as exc:
        view.rmdir()
        pytest.skip(f"cannot make a read-only bind mount here: {exc}")
    try:
        _run("mount", "-o", "remount,bind,ro", str(view))
        yield view
    finally:
        _unmount(view)
        view.rmdir()


@contextlib.contextmanager
def small_disk(folder: Path, megabytes: int) -> Iterator[Path]:
    """A tmpfs of ``megabytes`` at ``folder`` (a real 'No space left on device' when full); root
    only. Yields the folder; :func:`grow` frees it."""
    folder.mkdir()
    try:
        _run("mount", "-t", "tmpfs", "-o", f"size={megabytes}m", "tmpfs", str(folder))
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {exc}")
    try:
        yield folder
    finally:
        _unmount(folder)


def grow(folder: Path, megabytes: int) -> None:
    """Give the tmpfs at ``folder`` more room (the experimenter freed the disk)."""
    _run("mount", "-o", f"remount,size={megabytes}m", str(folder))

