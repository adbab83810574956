"""One SQLite file per participant (``<study>/<code>.sqlite``), written through sqlite-utils.

Durability: WAL journal with ``synchronous=FULL``, so a committed transaction survives a crash, a kill
or a power cut. Every user action is written in one :meth:`ParticipantStore.transaction` (its event and
its rows together) before it is acknowledged; a kill mid-write leaves the file as it was before.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from sqlite_utils import Database

from session_store.errors import CorruptStoreError, SchemaVersionError, StoreError
from session_store.models import (
    Answer,
    Comparison,
    Event,
    LearnerSnapshotRow,
    Participant,
    Placement,
    StudyConfig,
    Trial,
    ValidationRating,
    check_participant_code,
)
from session_store.schema import MIGRATIONS, SCHEMA_VERSION, TABLES, sample_column_names

SUFFIX = ".sqlite"


def participant_path(study_dir: Path, code: str) -> Path:
    return Path(study_dir) / f"{check_participant_code(code)}{SUFFIX}"


def participant_codes(study_dir: Path) -> list[str]:
    """Codes of the participant databases in a study folder, sorted."""
    return sorted(p.stem for p in Path(study_dir).glob(f"*{SUFFIX}"))


class ParticipantStore:
    """The database of one participant. Use :meth:`create` or :meth:`open`."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        try:
            self.db = Database(self.path)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA synchronous=FULL")
            self.db.execute("PRAGMA foreign_keys=ON")
            result = self.db.execute("PRAGMA quick_check").fetchone()[0]
        except sqlite3.DatabaseError as exc:
            raise CorruptStoreError(f"{self.path} is not a readable SQLite database: {exc}") from exc
        try:
            if result != "ok":
                raise CorruptStoreError(f"{self.path} fails SQLite's integrity check: {result}")
            self._migrate()
        except BaseException:
            self.db.close()
            raise

    # -- opening --------------------------------------------------------------------------------
    @classmethod
    def create(cls, study_dir: Path, code: str, config: StudyConfig) -> ParticipantStore:
        """A new database for participant ``code``; refuses an unsafe code or one that already
        has a database, before anything is written."""
        path = participant_path(study_dir, code)
        participant = Participant(code=code, config=config)
        if cls.exists(study_dir, code):
            raise StoreError(f"participant {participant.code!r} already has a database at {path}; "
                             "resume it instead")
        for leftover in (path, path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")):
            leftover.unlink(missing_ok=True)  # a creation that was interrupted before it committed
        path.parent.mkdir(parents=True, exist_ok=True)
        store = cls(path)
        with store.transaction():
            store.db["participant"].insert({"code": participant.code,
                                            "created_at": participant.created_at,
                                            "config": participant.config.model_dump_json()})
        return store

    @classmethod
    def open(cls, study_dir: Path, code: str) -> ParticipantStore:
        if not cls.exists(study_dir, code):
            raise StoreError(f"participant {code!r} has no session in {study_dir}")
        return cls(participant_path(study_dir, code))

    @staticmethod
    def exists(study_dir: Path, code: str) -> bool:
        """True if ``code`` has a database whose creation committed (its participant row)."""
        path = participant_path(study_dir, code)
        if not path.exists():
            return False
        try:
            with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as conn:
                return conn.execute("SELECT count(*) FROM participant").fetchone()[0] == 1
        except sqlite3.DatabaseError:
            return True  # unreadable: let open() say what is wrong with it

    def _migrate(self) -> None:
        version = self.db.execute("PRAGMA user_version").fetchone()[0]
        if version > SCHEMA_VERSION:
            raise SchemaVersionError(
                f"{self.path} has schema version {version}; this handover-lab reads versions up to "
                f"{SCHEMA_VERSION}: update handover-lab to open it")
        if version == 0 and self.db.table_names():
            raise SchemaVersionError(f"{self.path} is an SQLite file but not a handover-lab database "
                                     f"(tables {self.db.table_names()[:5]}, no schema version)")
        for target in range(version + 1, SCHEMA_VERSION + 1):
            with self.transaction():
                MIGRATIONS[target](self.db)
                self.db.execute(f"PRAGMA user_version = {target}")

    def close(self) -> None:
        self.db.close()

    @contextlib.contextmanager
    def transaction(self) -> Iterator[None]:
        """All writes inside commit together or not at all (nested blocks are savepoints)."""
        with self.db.atomic():
            yield

    # -- writing --------------------------------------------------------------------------------
    def append_event(self, event: Event) -> Event:
        row = event.model_dump(mode="json", exclude={"seq"})
        row["payload"] = json.dumps(row["payload"], sort_keys=True)
        seq = self.db["events"].insert(row).last_pk
        return event.model_copy(update={"seq": seq})

    def put_trial(self, trial: Trial) -> None:
        """Insert a started trial or replace it with its ended version."""
        self.db["trials"].upsert(trial.model_dump(mode="json"), pk="trial_index")

    def add_samples(self, trial_index: int, columns: dict[str, np.ndarray]) -> int:
        """The control loop's per-cycle rows of a trial (NaN is stored as NULL)."""
        flat = []
        for name in columns:
            values = np.asarray(columns[name], dtype=float)
            flat.extend([values] if values.ndim == 1 else list(values.T))
        names = sample_column_names()
        matrix = np.column_stack(flat) if flat else np.empty((0, len(names)))
        matrix = np.where(np.isfinite(matrix), matrix, np.nan)
        rows = ({"trial_index": trial_index, "cycle": cycle,
                 **{n: (None if v != v else float(v)) for n, v in zip(names, row, strict=True)}}
                for cycle, row in enumerate(matrix.tolist()))
        self.db["samples"].insert_all(rows, batch_size=500)
        return len(matrix)

    def add(self, row: Placement | Comparison | ValidationRating | Answer | LearnerSnapshotRow) -> None:
        table = next(name for name, (model, _) in TABLES.items() if isinstance(row, model))
        self.db[table].insert(row.model_dump(mode="json"))

    # -- reading --------------------------------------------------------------------------------
    def participant(self) -> Participant:
        row = next(self.db["participant"].rows)
        return Participant(code=row["code"], created_at=row["created_at"],
                           config=StudyConfig.model_validate_json(row["config"]))

    def events(self) -> list[Event]:
        return [Event.model_validate({**row, "payload": json.loads(row["payload"])})
                for row in self.db["events"].rows_where(order_by="seq")]

    def rows(self, table: str, order_by: str | None = None) -> list[Any]:
        """Rows of a table as their pydantic models (``samples`` excepted: see :meth:`samples`)."""
        model, pk = TABLES[table]
        order = order_by or (pk if isinstance(pk, str) else ", ".join(pk))
        return [model.model_validate(row) for row in self.db[table].rows_where(order_by=order)]

    def samples(self, trial_index: int) -> list[dict[str, Any]]:
        return list(self.db["samples"].rows_where("trial_index = ?", [trial_index],
                                                  order_by="cycle"))

    def counts(self) -> dict[str, int]:
        return {table: self.db[table].count for table in [*TABLES, "samples"]}
