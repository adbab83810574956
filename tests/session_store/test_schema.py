"""The schema is frozen per version and later versions are migrations.

``data/main-v2-M01.sqlite`` is a whole short session (9 interactions, placements, a validation rating,
Q1–Q3) written by main before provenance existed (schema version 2; its samples cut to 20 cycles a
trial to keep the file small). Version 1 files are made from it as version 1 left them: without the
cycle's columns, ``user_version`` 1. ``data/main-v3-M03.sqlite`` is the same kind of session written
by main at schema version 3 (commit 9fc03e6, before the joint angles; the simulated participant
placed and rated, so its rows carry that ``actor``).
"""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pytest
from support.engine import new_engine

from app.protocol.engine import SessionEngine
from app.protocol.rig import rig_of
from app.protocol.state import Step
from app.protocol.stored_session import recorded_session
from app.session.config import LabConfig
from session_store.schema import (
    SCHEMA_VERSION,
    TABLES,
    V1_SAMPLE_COLUMNS,
    V1_TABLES,
    V2_SAMPLE_COLUMNS,
    V2_TRIAL_COLUMNS,
    V3_PROVENANCE_TABLES,
    V4_SAMPLE_COLUMNS,
    V6_TRIAL_COLUMNS,
    columns_of,
)
from session_store.store import ParticipantStore

MAIN_FILE = Path(__file__).parent / "data" / "main-v2-M01.sqlite"
MAIN_V3_FILE = Path(__file__).parent / "data" / "main-v3-M03.sqlite"
SQL_TYPE = {int: "INTEGER", float: "REAL", str: "TEXT"}


def _columns(path: Path) -> dict[str, dict[str, str]]:
    with sqlite3.connect(path) as conn:
        tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
        return {t: {r[1]: r[2] for r in conn.execute(f'PRAGMA table_info("{t}")')} for t in tables}


def _counts(path: Path) -> dict[str, int]:
    with sqlite3.connect(path) as conn:
        return {t: conn.execute(f'SELECT count(*) FROM "{t}"').fetchone()[0]
                for t in [*V1_TABLES, "samples"]}


def _old_file(tmp_path: Path, version: int) -> Path:
    """A copy of a file main wrote at ``version`` (1: the version-2 file without version 2's columns)."""
    if version == 3:
        path = tmp_path / "M03.sqlite"
        shutil.copy(MAIN_V3_FILE, path)
        return path
    path = tmp_path / "M01.sqlite"
    shutil.copy(MAIN_FILE, path)
    if version == 1:
        with sqlite3.connect(path) as conn:
            for table, columns in (("trials", V2_TRIAL_COLUMNS), ("samples", V2_SAMPLE_COLUMNS)):
                for column in columns:
                    conn.execute(f"ALTER TABLE {table} DROP COLUMN {column}")
            conn.execute("PRAGMA user_version = 1")
    return path


def test_the_frozen_version_1_is_what_main_wrote_without_the_cycle_columns():
    written = _columns(MAIN_FILE)
    for table, (columns, _) in V1_TABLES.items():
        later = V2_TRIAL_COLUMNS if table == "trials" else {}
        assert {n: t for n, t in written[table].items() if n not in later} == \
            {n: SQL_TYPE[t] for n, t in columns.items()}, table
    samples = {n for n in written["samples"] if n not in V2_SAMPLE_COLUMNS}
    assert samples == {"trial_index", "cycle", *V1_SAMPLE_COLUMNS}


def test_the_version_3_file_main_wrote_has_exactly_the_columns_of_versions_1_to_3():
    written = _columns(MAIN_V3_FILE)
    added = {"trials": V2_TRIAL_COLUMNS} | {table: {"actor": str} for table in V3_PROVENANCE_TABLES}
    for table, (columns, _) in V1_TABLES.items():
        assert written[table] == {n: SQL_TYPE[t] for n, t in (columns | added.get(table, {})).items()}
    assert set(written["samples"]) == {"trial_index", "cycle", *V1_SAMPLE_COLUMNS, *V2_SAMPLE_COLUMNS}


@pytest.mark.parametrize("version", [1, 2, 3])
def test_an_old_file_migrates_to_the_current_version_and_keeps_every_row(tmp_path, version):
    path = _old_file(tmp_path, version)
    code = path.stem
    before = _counts(path)
    kept = ", ".join(_columns(path)["samples"])
    with sqlite3.connect(path) as conn:
        old_samples = conn.execute(f"SELECT {kept} FROM samples ORDER BY trial_index, cycle").fetchall()
    store = ParticipantStore.open(tmp_path, code)
    try:
        assert store.db.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 6
        assert store.rows("hints") == []  # no hints before version 5 (coactive hints)
        # no safety record before version 6: every trial has the columns, empty
        safety = ", ".join(V6_TRIAL_COLUMNS)
        assert store.db.execute(f"SELECT count(*) FROM trials WHERE coalesce({safety}) IS NOT NULL"
                                ).fetchone()[0] == 0
        assert all(t.min_distance_m is None for t in store.rows("trials"))
        assert set(V2_TRIAL_COLUMNS) <= set(store.db["trials"].columns_dict)
        assert set(V2_SAMPLE_COLUMNS) <= set(store.db["samples"].columns_dict)
        for table in V3_PROVENANCE_TABLES:
            assert "actor" in store.db[table].columns_dict
            rows = store.rows(table)
            # the origin was not recorded before version 3; the simulated participant's after it
            assert rows and {row.actor for row in rows} == \
                ({None} if version < 3 else {"simulated_participant"})
        # the joint angles were not recorded before version 4: every sample keeps them empty and
        # every value it had as it was
        joints = ", ".join(V4_SAMPLE_COLUMNS)
        assert store.db.execute(f"SELECT count(*) FROM samples WHERE coalesce({joints}) IS NOT NULL"
                                ).fetchone()[0] == 0
        assert store.db.execute(f"SELECT {kept} FROM samples ORDER BY trial_index, cycle"
                                ).fetchall() == old_samples
    finally:
        store.close()
    assert _counts(path) == before
    # The migrated file has the columns of a file made today, which are the models' columns.
    fresh = new_engine(tmp_path / "fresh")
    fresh.close()
    migrated, made = _columns(path), _columns(tmp_path / "fresh" / "S01.sqlite")
    assert {t: set(c) for t, c in migrated.items()} == {t: set(c) for t, c in made.items()}
    for table, (model, _) in TABLES.items():
        assert set(made[table]) == set(columns_of(model)), table


def test_the_log_of_an_old_session_replays_as_typed_events(tmp_path):
    _old_file(tmp_path, 1)
    engine = SessionEngine.resume(tmp_path, "M01")
    try:
        assert engine.state.step is Step.DONE and engine.state.completed == 9
        assert engine.state.answers.keys() == {"Q1", "Q2", "Q3"}
    finally:
        engine.close()


@pytest.mark.parametrize(("stored", "code"), [(MAIN_FILE, "M01"), (MAIN_V3_FILE, "M03")])
def test_an_old_mock_arm_session_is_on_the_same_rig_after_the_ur_host_lost_its_default(
        tmp_path, stored, code):
    """These sessions recorded [ur] host = 192.168.1.10 on the mock arm, the old default. The host
    has no default any more, and a mock arm's [ur] table is no part of its rig: a resume on the
    default lab config is not a rig change (before, it was refused as one: ur.host → None)."""
    shutil.copy(stored, tmp_path / f"{code}.sqlite")
    recorded = recorded_session(tmp_path, code).rig
    assert recorded["arm"] == {"kind": "mock"} and recorded["ur"] is None
    assert recorded == rig_of(LabConfig().model_dump(mode="json"))  # the runner's _rig_identity
