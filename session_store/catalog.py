"""What a study folder holds, read without opening any database for writing: each participant's
stored session plan (for the seeds already in use). Unreadable files are skipped here; ``doctor``
and ``export`` say what is wrong with them."""

from __future__ import annotations

import json
import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any

from session_store.errors import StoreError
from session_store.file_check import connect_read_only
from session_store.paths import participant_codes, participant_path


def stored_config(database: Path) -> dict[str, Any] | None:
    """The session plan stored in one participant database (None if it has none or is unreadable)."""
    try:
        with closing(connect_read_only(database)) as conn:
            row = conn.execute("SELECT config FROM participant").fetchone()
        return None if row is None else json.loads(row[0])
    except (sqlite3.Error, StoreError, json.JSONDecodeError, TypeError):
        return None


def stored_configs(study_dir: Path) -> dict[str, dict[str, Any]]:
    """code → stored session plan, for every readable participant database of ``study_dir``."""
    configs = {}
    for code in participant_codes(study_dir) if Path(study_dir).is_dir() else []:
        try:
            database = participant_path(study_dir, code)
        except StoreError:  # a file name that is no participant code
            continue
        config = stored_config(database)
        if config is not None:
            configs[code] = config
    return configs
