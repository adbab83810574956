"""One SQLite file per participant (``<study>/<code>.sqlite``), written through sqlite-utils.

Durability: WAL journal with ``synchronous=FULL``, so a committed transaction survives a crash, a kill
or a power cut. A writer that closes cleanly leaves the file in rollback-journal mode, its WAL folded
in: a plain file that readers open read-only without writing beside it (a reader of a WAL database
creates ``-wal`` and ``-shm``, and cannot remove them). Every user action is written in one
:meth:`ParticipantStore.transaction` (its event and its rows together) before it is acknowledged; a
kill mid-write leaves the file as it was before.
"""

from __future__ import annotations

import contextlib
import json
import logging
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from session_store import lock as writer_lock
from session_store.database import Database, quote_identifier
from session_store.errors import CorruptStoreError, SchemaVersionError, StoreError
from session_store.file_check import (
    check_participant_file,
    connect_read_only,
    explained_writes,
    write_failure,
)
from session_store.models import (
    Answer,
    Comparison,
    Event,
    HintRow,
    LearnerSnapshotRow,
    Participant,
    Placement,
    Trial,
    ValidationRating,
)
from session_store.paths import SUFFIX, participant_codes, participant_path, refuse_case_twin
from session_store.schema import MIGRATIONS, SCHEMA_VERSION, TABLES, sample_column_names

__all__ = ["SUFFIX", "ParticipantStore", "participant_codes", "participant_path", "sample_matrix"]

log = logging.getLogger(__name__)


def sample_matrix(columns: dict[str, np.ndarray]) -> np.ndarray:
    """A trial's recorded columns (the loop's, in ``sample_column_names`` order, a vector column
    as one column per component) as one row per control cycle."""
    flat = []
    for name in columns:
        values = np.asarray(columns[name], dtype=float)
        flat.extend([values] if values.ndim == 1 else list(values.T))
    return np.column_stack(flat) if flat else np.empty((0, len(sample_column_names())))


class ParticipantStore:
    """The database of one participant. :meth:`create` and :meth:`open_for_writing` hold the
    participant's writer lock (:mod:`session_store.lock`) until :meth:`close`; :meth:`open` is for
    readers (or, to read without touching the file, :func:`session_store.read_only_copy.reading`, which
    passes the ``connection`` of an in-memory copy)."""

    def __init__(self, path: Path, connection: sqlite3.Connection | None = None) -> None:
        self.path = Path(path)
        self.lock: writer_lock.WriterLock | None = None
        try:
            self.db = Database(connection or self.path)
            self.db.execute("PRAGMA journal_mode=WAL")
            self.db.execute("PRAGMA synchronous=FULL")
            self.db.execute("PRAGMA foreign_keys=ON")
            result = self.db.execute("PRAGMA quick_check").fetchone()[0]
        except sqlite3.DatabaseError as exc:
            raise write_failure(exc, self.path) or CorruptStoreError(
                f"{self.path} is not a readable SQLite database: {exc}") from exc
        try:
            if result != "ok":
                raise CorruptStoreError(f"{self.path} fails SQLite's integrity check: {result}")
            self._migrate()
        except BaseException:
            self.db.close()
            raise

    # -- opening --------------------------------------------------------------------------------
    @classmethod
    def create(cls, study_dir: Path, code: str, config: BaseModel) -> ParticipantStore:
        """A new database for participant ``code`` with its session plan ``config``; refuses an
        unsafe code, one that already has a database or one another writer holds, before anything
        is written."""
        path = participant_path(study_dir, code)
        participant = Participant(code=code, config=config.model_dump(mode="json"))
        refuse_case_twin(study_dir, code)
        if cls.exists(study_dir, code):
            raise StoreError(f"participant {participant.code!r} already has a database at {path}; "
                             "resume it instead")
        held = writer_lock.claim(path)
        try:
            if cls.exists(study_dir, code):  # created by the writer that held the lock before
                raise StoreError(f"participant {code!r} already has a database at {path}; resume "
                                 "it instead")
            for leftover in (path, path.with_name(path.name + "-wal"),
                             path.with_name(path.name + "-shm")):
                leftover.unlink(missing_ok=True)  # a creation interrupted before it committed
            store = cls(path)
        except BaseException:
            writer_lock.unclaim(held)
            raise
        store.lock = held
        with store.transaction():
            store.db.table("participant").insert({"code": participant.code,
                                                  "created_at": participant.created_at,
                                                  "config": config.model_dump_json()})
        return store

    @classmethod
    def open(cls, study_dir: Path, code: str) -> ParticipantStore:
        """Open for reading (export, report): takes no lock, so it works during a session."""
        if not cls.exists(study_dir, code):
            raise StoreError(f"participant {code!r} has no session in {study_dir}")
        check_participant_file(participant_path(study_dir, code), code)
        return cls(participant_path(study_dir, code))

    @classmethod
    def open_for_writing(cls, study_dir: Path, code: str) -> ParticipantStore:
        """Open to continue the session: refused, before anything is written, while another
        writer holds the participant (the message names it)."""
        path = participant_path(study_dir, code)
        if not cls.exists(study_dir, code):
            raise StoreError(f"participant {code!r} has no session in {study_dir}")
        check_participant_file(path, code)
        held = writer_lock.claim(path)
        try:
            store = cls(path)
        except BaseException:
            writer_lock.unclaim(held)
            raise
        store.lock = held
        return store

    @staticmethod
    def exists(study_dir: Path, code: str) -> bool:
        """True if ``code`` has a database whose creation committed (its participant row)."""
        path = participant_path(study_dir, code)
        if not path.exists():
            return False
        try:
            with contextlib.closing(connect_read_only(path)) as conn:
                return conn.execute("SELECT count(*) FROM participant").fetchone()[0] == 1
        except (sqlite3.DatabaseError, StoreError):
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
        if self.lock is not None:
            self._leave_plain_file()
        self.db.close()
        if self.lock is not None:
            writer_lock.unclaim(self.lock)
            self.lock = None

    def _leave_plain_file(self) -> None:
        """The writer's clean close: fold the WAL in and switch to rollback-journal mode, which
        removes ``-wal`` and ``-shm`` (the next writer turns WAL on again). While a reader has the
        file open the switch is refused (busy) and the file stays in WAL mode: nothing is lost."""
        try:
            self.db.execute("PRAGMA journal_mode=DELETE")
        except sqlite3.OperationalError as exc:
            log.info("%s stays in WAL mode (%s): a reader has it open", self.path, exc)

    @contextlib.contextmanager
    def transaction(self) -> Iterator[None]:
        """All writes inside commit together or not at all (nested blocks are savepoints); a failed
        write (a full disk) raises StoreWriteError and leaves the file as it was."""
        with explained_writes(self.path), self.db.atomic():
            yield

    # -- writing --------------------------------------------------------------------------------
    def append_event(self, event: Event) -> Event:
        row = event.model_dump(mode="json", exclude={"seq"})
        row["payload"] = json.dumps(row["payload"], sort_keys=True)
        seq = self.db.table("events").insert(row).last_pk
        return event.model_copy(update={"seq": seq})

    def put_trial(self, trial: Trial) -> None:
        """Insert a started trial or replace it with its ended version."""
        self.db.table("trials").upsert(trial.model_dump(mode="json"), pk="trial_index")

    def add_samples(self, trial_index: int, columns: dict[str, np.ndarray]) -> int:
        """The control loop's per-cycle rows of a trial (NaN and ±inf are stored as NULL).

        One ``executemany`` of the table's INSERT: sqlite-utils' ``insert_all`` converts each of a
        trial's ~78,000 values in Python (225 ms of CPU for a 3.6 s trial at 500 Hz, at the end of
        every trial, in the process that serves the screens); SQLite binds them in C (34 ms;
        ``benchmarks/trial_end.py``). The table and its columns are sqlite-utils' own (``schema``).
        """
        names, matrix = sample_column_names(), sample_matrix(columns)
        rows = np.empty((len(matrix), len(names) + 2), dtype=object)
        rows[:, 0], rows[:, 1], rows[:, 2:] = trial_index, range(len(matrix)), matrix
        rows[:, 2:][~np.isfinite(matrix)] = None
        quoted = ", ".join(map(quote_identifier, ["trial_index", "cycle", *names]))
        insert = f"INSERT INTO samples ({quoted}) VALUES ({', '.join('?' * (len(names) + 2))})"
        self.db.conn.executemany(insert, rows.tolist())
        return len(matrix)

    def add(self, row: Placement | Comparison | ValidationRating | Answer | HintRow
            | LearnerSnapshotRow) -> None:
        table = next(name for name, (model, _) in TABLES.items() if isinstance(row, model))
        self.db.table(table).insert(row.model_dump(mode="json"))

    # -- reading --------------------------------------------------------------------------------
    def participant(self) -> Participant:
        row = next(self.db["participant"].rows)
        return Participant(code=row["code"], created_at=row["created_at"],
                           config=json.loads(row["config"]))

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
