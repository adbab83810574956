"""Export a study folder as tidy tables: one file per kind of row, all participants merged, the
participant code in every row, plus consistent copies of the .sqlite files. :func:`load_study` gives
the same tables in memory (the analysis reads a study folder through it).

The dtypes of every column are documented once, in :data:`DTYPES` (rendered in ``docs/data.md``), and
:func:`read_table` loads an exported table with them.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
from collections.abc import Collection, Mapping
from collections.abc import Set as AbstractSet
from pathlib import Path
from typing import NamedTuple

import pandas as pd
from pydantic import BaseModel, ValidationError

from robot_io.errors import explain
from session_store.errors import CorruptStoreError, StoreError, StoreWriteError
from session_store.file_check import explained_writes
from session_store.models import (
    Answer,
    Comparison,
    Event,
    HintRow,
    LearnerSnapshotRow,
    Placement,
    Trial,
    ValidationRating,
)
from session_store.paths import EXPORT_FORMATS
from session_store.read_only_copy import reading
from session_store.schema import TABLES, columns_of, sample_column_names, sample_columns
from session_store.store import SUFFIX, ParticipantStore, participant_codes

#: The participants table: dtype and meaning of each column.
PARTICIPANT_COLUMNS: dict[str, tuple[str, str]] = {
    "participant": ("string", "pseudonymous participant code"),
    "scenario": ("string", "straightforward or perturbed (Sect. V-A)"),
    "seed": ("Int64", "seed of the session"),
    "created_at": ("string", "UTC ISO-8601 time the session was created"),
    "completed": ("Int64", "completed interactions (34 for a whole session with the defaults)"),
    "config": ("string", "the study configuration as JSON (counts, bounds, controller; "
                         "assignment: what the [study] plan proposed for the participant)"),
}
SNAPSHOT_EXCLUDED = {"state"}  # the learner's own JSON stays in the .sqlite file


def _pandas_dtype(sqlite_type: type) -> str:
    return {int: "Int64", float: "float64", str: "string"}[sqlite_type]


def _model_dtypes(model: type[BaseModel], exclude: AbstractSet[str] = frozenset()) -> dict[str, str]:
    dtypes = {"participant": "string"}
    for name, sqlite_type in columns_of(model).items():
        if name in exclude:
            continue
        annotation = model.model_fields[name].annotation
        dtypes[name] = "boolean" if annotation in (bool, bool | None) else _pandas_dtype(sqlite_type)
    return dtypes


DTYPES: dict[str, dict[str, str]] = {
    "participants": {name: dtype for name, (dtype, _) in PARTICIPANT_COLUMNS.items()},
    "trials": _model_dtypes(Trial),
    "placements": _model_dtypes(Placement),
    "comparisons": _model_dtypes(Comparison),
    "validation_ratings": _model_dtypes(ValidationRating),
    "answers": _model_dtypes(Answer),
    "hints": _model_dtypes(HintRow),
    "learner_snapshots": _model_dtypes(LearnerSnapshotRow, SNAPSHOT_EXCLUDED),
    "events": _model_dtypes(Event),
    "samples": {"participant": "string", "trial_index": "Int64", "cycle": "Int64"}
    | {name: "float64" for name in sample_column_names()},
}

#: What one row of each exported table is.
ROW_MEANING = {
    "participants": "one participant: scenario, seed, completed interactions, study config (JSON)",
    "trials": "one attempt at an interaction (aborted attempts included, outcome says which)",
    "placements": "one placement on the relative scale",
    "comparisons": "one pairwise comparison winner ≻ loser implied by a placement (eq. 11)",
    "validation_ratings": "the second interaction of a validation pair rated against the first",
    "answers": "one answer to a question of the questionnaire (Q1, Q2, …)",
    "hints": "one coactive hint after a placement ([protocol] coactive): θ' preferred to θ",
    "learner_snapshots": "the learner after planning the next θ: θ*, fit status",
    "events": "one line of the append-only event log (payload as JSON)",
    "samples": "one control cycle of a trial (t, DMP state, hand, coupling, poses)",
}


def _participant_frame(store: ParticipantStore) -> pd.DataFrame:
    participant = store.participant()
    completed = store.db.execute("SELECT count(*) FROM trials WHERE outcome = 'completed'"
                                 ).fetchone()[0]
    return pd.DataFrame([{"participant": participant.code,
                          "scenario": participant.config["scenario"],
                          "seed": participant.config["seed"], "created_at": participant.created_at,
                          "completed": completed,
                          "config": json.dumps(participant.config, separators=(",", ":"))}])


def _table_frame(store: ParticipantStore, table: str,
                 sample_phases: Collection[str] | None = None) -> pd.DataFrame:
    columns = [c for c in DTYPES[table] if c != "participant"]
    quoted = ", ".join(f'"{c}"' for c in columns)
    order = "trial_index, cycle" if table == "samples" else "rowid"
    where, params = "", []
    if table == "samples" and sample_phases is not None:
        marks = ", ".join("?" for _ in sample_phases)
        where = f" WHERE trial_index IN (SELECT trial_index FROM trials WHERE phase IN ({marks}))"
        params = list(sample_phases)
    frame = pd.read_sql_query(f'SELECT {quoted} FROM "{table}"{where} ORDER BY {order}',
                              store.db.conn, params=params)
    frame.insert(0, "participant", store.participant().code)
    return frame


def participant_tables(store: ParticipantStore, tables: Collection[str] = tuple(DTYPES),
                       sample_phases: Collection[str] | None = None) -> dict[str, pd.DataFrame]:
    """The tidy ``tables`` of one participant's database (``samples`` only of trials in
    ``sample_phases`` when given: the samples are by far the largest table)."""
    return {table: _participant_frame(store) if table == "participants"
            else _table_frame(store, table, sample_phases) for table in tables}


def _study_codes(study_dir: Path) -> list[str]:
    codes = participant_codes(study_dir)
    if not codes:
        raise StoreError(f"{study_dir} holds no participant database (*.sqlite)")
    return codes


def _merged(parts: list[dict[str, pd.DataFrame]], tables: Collection[str]) -> dict[str, pd.DataFrame]:
    """Concatenate per-participant tables and apply the documented dtypes."""
    return {table: pd.concat([part[table] for part in parts], ignore_index=True).astype(DTYPES[table])
            for table in tables}


def _copy(store: ParticipantStore, target: Path) -> None:
    """A consistent copy of a participant's database at ``target``."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with explained_writes(target), contextlib.closing(sqlite3.connect(target)) as copy:
        store.db.conn.backup(copy)


def _read_study(study_dir: Path, tables: Collection[str], sample_phases: Collection[str] | None,
                skip_unreadable: bool, copies: Path | None = None,
                exclude: Mapping[Path, str] | None = None
                ) -> tuple[list[dict[str, pd.DataFrame]], dict[Path, str]]:
    """Every participant's tables (and, with ``copies``, a copy of their database there), read
    without writing to the study folder. A file that cannot be read raises its StoreError, or with
    ``skip_unreadable`` is left out and returned as path → why; so is a file in ``exclude`` (path →
    why the caller refuses it). Only the caller says what was left out (a log line here as well
    made the export command say each one twice). Nothing readable raises."""
    parts, unreadable = [], {}
    for code in _study_codes(study_dir):
        path = Path(study_dir) / f"{code}{SUFFIX}"
        if exclude and path in exclude:
            unreadable[path] = exclude[path]
            continue
        try:
            with reading(study_dir, code) as store:
                try:
                    part = participant_tables(store, tables, sample_phases)
                except (sqlite3.DatabaseError, ValidationError) as exc:
                    raise CorruptStoreError(f"{path} could not be read: {explain(exc)}") from exc
                if copies is not None:
                    _copy(store, copies / f"{code}{SUFFIX}")
            parts.append(part)
        except StoreWriteError:
            raise  # the output, not this participant's file, failed
        except StoreError as exc:
            if not skip_unreadable:
                raise
            unreadable[path] = str(exc)
    if not parts:
        raise StoreError(f"{study_dir} holds no readable participant database: "
                         + "; ".join(unreadable.values()))
    return parts, unreadable


class StudyTables(NamedTuple):
    """All participants' tidy tables, and the databases that could not be read (path → why)."""

    tables: dict[str, pd.DataFrame]
    unreadable: dict[Path, str]


def load_study(study_dir: Path, tables: Collection[str] = tuple(DTYPES), *,
               sample_phases: Collection[str] | None = None,
               skip_unreadable: bool = False, exclude: Mapping[Path, str] | None = None
               ) -> StudyTables:
    """The tidy tables of a study folder in memory, as :func:`export_study` writes them and
    :func:`read_table` reads them back. Nothing is written to the study folder (a read-only one
    is read as it is).

    A database that cannot be read (empty, another schema version, corrupt, not ours, or holding
    another participant's session than its name says) raises its :class:`StoreError`; with
    ``skip_unreadable`` it is left out and listed in ``unreadable`` with the error's message
    instead; so is a database in ``exclude`` (path → why the caller refuses it: ``handover doctor``
    found it BAD). An empty folder, or one in which nothing is readable, raises.
    """
    unknown = set(tables) - set(DTYPES)
    if unknown:
        raise StoreError(f"tables = {sorted(unknown)} are not among {list(DTYPES)}")
    parts, unreadable = _read_study(study_dir, tables, sample_phases, skip_unreadable,
                                    exclude=exclude)
    return StudyTables(_merged(parts, tables), unreadable)


class Export(NamedTuple):
    """What :func:`export_study` wrote: table → (file, rows), and the databases it left out
    (path → why), which ``left_out.csv`` lists too."""

    written: dict[str, tuple[Path, int]]
    left_out: dict[Path, str]


#: The file of an export that lists the databases it left out (header only when none).
LEFT_OUT_FILE = "left_out.csv"


def refuse_inside_study(out_dir: Path, study_dir: Path, writer: str = "export") -> None:
    """Refuse an output folder that is the study folder, lies inside it, or would put the
    ``sqlite/`` copies there: an export (or a report, ``writer``) beside the participants'
    databases would be overwritten by the next one and read by nothing that reads a study."""
    study, out = Path(study_dir).resolve(), Path(out_dir).resolve()
    if out == study or study in out.parents or out / "sqlite" == study:
        where = "would write its sqlite/ copies into" if out / "sqlite" == study else "is inside"
        raise StoreError(f"--out {out_dir} {where} the study folder {study_dir}: {writer} never "
                         "writes into a study folder; choose an output folder outside it")


def export_study(study_dir: Path, out_dir: Path, fmt: str = "csv",
                 exclude: Mapping[Path, str] | None = None) -> Export:
    """Write every table of :data:`DTYPES` for all readable participants of ``study_dir`` into
    ``out_dir`` (plus ``sqlite/<code>.sqlite`` copies). A database that cannot be read, or that is
    in ``exclude`` (path → why), is left out and listed (in the result and in ``left_out.csv``);
    the others are exported all the same.
    Nothing is written when nothing is readable, and nothing ever to the study folder."""
    if fmt not in EXPORT_FORMATS:
        raise StoreError(f"format = {fmt!r} is not one of {EXPORT_FORMATS}")
    out_dir = Path(out_dir)
    refuse_inside_study(out_dir, study_dir)
    parts, left_out = _read_study(study_dir, DTYPES, None, skip_unreadable=True,
                                  copies=out_dir / "sqlite", exclude=exclude)
    written = {}
    for table, frame in _merged(parts, DTYPES).items():
        path = out_dir / f"{table}.{fmt}"
        if fmt == "csv":
            frame.to_csv(path, index=False)
        else:
            frame.to_parquet(path, index=False)
        written[table] = (path, len(frame))
    pd.DataFrame({"file": [str(p) for p in left_out], "reason": list(left_out.values())},
                 dtype="string").to_csv(out_dir / LEFT_OUT_FILE, index=False)
    return Export(written, left_out)


def read_table(out_dir: Path, table: str) -> pd.DataFrame:
    """Load an exported table (CSV or Parquet) with its documented dtypes."""
    out_dir = Path(out_dir)
    if (out_dir / f"{table}.parquet").exists():
        return pd.read_parquet(out_dir / f"{table}.parquet").astype(DTYPES[table])
    return pd.read_csv(out_dir / f"{table}.csv", dtype=DTYPES[table], keep_default_na=True)


def column_meaning(table: str, column: str, models: dict[str, type[BaseModel]]) -> str:
    if column == "participant":
        return PARTICIPANT_COLUMNS["participant"][1]
    if table == "participants":
        return PARTICIPANT_COLUMNS[column][1]
    if table == "samples":
        return {"trial_index": "the trial", "cycle": "control cycle 0…"}.get(
            column) or sample_columns()[column]
    return models[table].model_fields[column].description or ""


def data_dictionary() -> str:
    """The Markdown data dictionary of the export (``docs/data.md`` embeds it)."""
    models: dict[str, type[BaseModel]] = {name: model for name, (model, _) in TABLES.items()}
    lines = []
    for table, dtypes in DTYPES.items():
        lines += [f"### `{table}`", "", ROW_MEANING[table], "", "| column | dtype | meaning |",
                  "| --- | --- | --- |"]
        for column, dtype in dtypes.items():
            lines.append(f"| `{column}` | {dtype} | {column_meaning(table, column, models)} |")
        lines.append("")
    return "\n".join(lines)
