"""Reading a participant database from a test beside the process that writes it."""

from __future__ import annotations

import sqlite3
from pathlib import Path


def event_count(path: Path) -> int:
    """Events written so far (0 before the session exists); read-only, beside the writer."""
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as conn:
            return conn.execute("SELECT count(*) FROM events").fetchone()[0]
    except sqlite3.Error:
        return 0
