"""Schema version 2 (the handover cycle's columns) migrates a version-1 file in place."""

from __future__ import annotations

import sqlite3

from session_helpers import drive_until, new_engine

from app.protocol.state import Step
from session_store.schema import V2_SAMPLE_COLUMNS, V2_TRIAL_COLUMNS
from session_store.store import ParticipantStore


def test_a_version_1_file_gains_the_cycle_columns_and_keeps_its_rows(tmp_path):
    engine = new_engine(tmp_path)
    drive_until(engine, Step.PLACE)
    engine.close()
    path = tmp_path / "S01.sqlite"
    with sqlite3.connect(path) as db:  # as version 1 made it: without the cycle's columns
        for table, columns in (("trials", V2_TRIAL_COLUMNS), ("samples", V2_SAMPLE_COLUMNS)):
            for column in columns:
                db.execute(f"ALTER TABLE {table} DROP COLUMN {column}")
        db.execute("PRAGMA user_version = 1")
        rows = db.execute("SELECT count(*) FROM samples").fetchone()[0]
    store = ParticipantStore.open(tmp_path, "S01")
    try:
        assert store.db.execute("PRAGMA user_version").fetchone()[0] == 2
        assert set(V2_TRIAL_COLUMNS) <= set(store.db["trials"].columns_dict)
        assert set(V2_SAMPLE_COLUMNS) <= set(store.db["samples"].columns_dict)
        assert store.db["samples"].count == rows > 0
        [trial] = store.rows("trials")
        assert trial.outcome.value == "completed" and trial.release_s is None
    finally:
        store.close()
