"""A participant database looked at without changing it (read-only, no migration, no lock): SQLite's
integrity check, the schema version, the participant row, the event log and the tables' own
consistency. ``handover doctor`` adds the protocol's replay on top (``app.protocol.doctor``)."""

from __future__ import annotations

import json
import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from session_store.errors import CorruptStoreError
from session_store.file_check import connect_read_only
from session_store.models import Event, Participant
from session_store.schema import SCHEMA_VERSION

#: Consistency of the derived tables, in SQL: (what is wrong, query listing the offending rows).
TABLE_CHECKS: tuple[tuple[str, str], ...] = (
    ("interaction completed by more than one trial",
     "SELECT interaction || ' (trials ' || group_concat(trial_index, ', ') || ')' FROM trials "
     "WHERE outcome = 'completed' GROUP BY interaction HAVING count(*) > 1"),
    ("placement of a trial that is not a completed trial",
     "SELECT p.trial_index FROM placements p LEFT JOIN trials t USING (trial_index) "
     "WHERE t.outcome IS NOT 'completed'"),
    ("interaction placed more than once",
     "SELECT interaction FROM placements GROUP BY interaction HAVING count(*) > 1"),
    ("validation rating of a trial that is not a completed trial",
     "SELECT v.trial_index FROM validation_ratings v LEFT JOIN trials t USING (trial_index) "
     "WHERE t.outcome IS NOT 'completed'"),
    ("samples of a trial that is not in the trials table, or that has not ended",
     "SELECT DISTINCT s.trial_index FROM samples s LEFT JOIN trials t USING (trial_index) "
     "WHERE t.outcome IS NULL"),
)
#: The tables derived from the event log, read whole for the doctor's comparison with it.
DERIVED_TABLES = ("trials", "placements", "comparisons", "validation_ratings", "answers", "hints")


class FileInspection(BaseModel):
    """What a database holds, and what is wrong with it at the storage level."""

    path: Path
    schema_version: int | None = None
    participant: Participant | None = None
    events: list[Event] = []
    #: the rows of :data:`DERIVED_TABLES`, as stored
    tables: dict[str, list[dict[str, Any]]] = {}
    problems: list[str] = []

    @property
    def readable(self) -> bool:
        return not self.problems and self.participant is not None


def _table_problems(conn: sqlite3.Connection) -> list[str]:
    problems = []
    for what, query in TABLE_CHECKS:
        offending = [str(row[0]) for row in conn.execute(query)]
        if offending:
            problems.append(f"{what}: {', '.join(offending[:10])}")
    return problems


def inspect_database(path: Path) -> FileInspection:
    """Look at ``path`` read-only; every problem is named, nothing raises for a bad file."""
    report = FileInspection(path=path)
    if Path(path).stat().st_size == 0:
        report.problems.append("empty file (0 bytes): not a handover-lab database")
        return report
    try:
        with closing(connect_read_only(path)) as conn:
            result = conn.execute("PRAGMA integrity_check").fetchall()
            if [r[0] for r in result] != ["ok"]:
                report.problems.append("fails SQLite's integrity check: "
                                       + "; ".join(r[0] for r in result[:5]))
                return report
            version = report.schema_version = conn.execute("PRAGMA user_version").fetchone()[0]
            if version > SCHEMA_VERSION:
                report.problems.append(f"schema version {version} is newer than this handover-lab "
                                       f"reads (up to {SCHEMA_VERSION}): update handover-lab")
                return report
            if version == 0:
                report.problems.append("an SQLite file but not a handover-lab database (no schema "
                                       "version)")
                return report
            conn.row_factory = sqlite3.Row
            row = conn.execute("SELECT code, created_at, config FROM participant").fetchone()
            if row is None:
                report.problems.append("no participant row: its creation never committed")
                return report
            report.participant = Participant(code=row["code"], created_at=row["created_at"],
                                             config=json.loads(row["config"]))
            for event in conn.execute("SELECT * FROM events ORDER BY seq"):
                try:
                    report.events.append(Event.model_validate(
                        {**dict(event), "payload": json.loads(event["payload"])}))
                except (ValidationError, json.JSONDecodeError) as exc:
                    report.problems.append(f"event {event['seq']} is not a stored event: {exc}")
            present = {r[0] for r in conn.execute("SELECT name FROM sqlite_master "
                                                  "WHERE type = 'table'")}
            # a file older than a table (read-only: not migrated) has none of its rows
            report.tables = {table: [dict(r) for r in conn.execute(f'SELECT * FROM "{table}"')]
                             if table in present else [] for table in DERIVED_TABLES}
            report.problems += _table_problems(conn)
    except sqlite3.DatabaseError as exc:
        report.problems.append(f"not a readable SQLite database: {exc}")
    except CorruptStoreError as exc:  # connect_read_only says why it cannot be read
        report.problems.append(str(exc))
    except (ValidationError, json.JSONDecodeError) as exc:
        report.problems.append(f"participant row unreadable: {exc}")
    return report
