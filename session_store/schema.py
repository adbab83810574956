"""The participant database's tables, derived from the pydantic models, and their migrations.

The schema version is SQLite's ``PRAGMA user_version``. ``MIGRATIONS[n]`` takes a database from
version n − 1 to n; opening a file runs the missing ones in order, each in its own transaction.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Callable
from enum import Enum

from pydantic import BaseModel
from sqlite_utils import Database

from robot_io.recorder import COLUMNS as SAMPLE_COLUMNS
from session_store.models import (
    Answer,
    Comparison,
    Event,
    LearnerSnapshotRow,
    Placement,
    Trial,
    ValidationRating,
)

AXES = ("x", "y", "z")


def sample_columns() -> dict[str, str]:
    """Flat columns of a trial sample row and their meaning: vectors become ``name_x`` … ``name_z``."""
    columns = {}
    for name, width, meaning in SAMPLE_COLUMNS:
        if width == 1:
            columns[name] = meaning
        for axis in AXES[:width] if width > 1 else ():
            columns[f"{name}_{axis}"] = f"{meaning}, {axis}"
    return columns


def sample_column_names() -> list[str]:
    return list(sample_columns())


def _sqlite_type(annotation: object) -> type:
    """The column type sqlite-utils should use for a pydantic field annotation."""
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        (inner,) = [a for a in typing.get_args(annotation) if a is not type(None)]
        return _sqlite_type(inner)
    if isinstance(annotation, type) and issubclass(annotation, bool):
        return int
    if isinstance(annotation, type) and issubclass(annotation, (int, float)):
        return float if issubclass(annotation, float) else int
    if isinstance(annotation, type) and issubclass(annotation, Enum):
        return str
    return str  # str, Literal[...] and JSON-encoded dicts


def columns_of(model: type[BaseModel]) -> dict[str, type]:
    return {name: _sqlite_type(field.annotation) for name, field in model.model_fields.items()}


#: table → (model, primary key)
TABLES: dict[str, tuple[type[BaseModel], str | tuple[str, ...]]] = {
    "trials": (Trial, "trial_index"),
    "placements": (Placement, "trial_index"),
    "comparisons": (Comparison, ("source", "winner", "loser")),
    "validation_ratings": (ValidationRating, "trial_index"),
    "answers": (Answer, "question"),
    "learner_snapshots": (LearnerSnapshotRow, "after_interaction"),
    "events": (Event, "seq"),
}


def _create_v1(db: Database) -> None:
    db["participant"].create({"code": str, "created_at": str, "config": str}, pk="code")
    for table, (model, pk) in TABLES.items():
        db[table].create(columns_of(model), pk=pk)
    sample_columns = {"trial_index": int, "cycle": int} | {name: float for name in
                                                         sample_column_names()}
    db["samples"].create(sample_columns, pk=("trial_index", "cycle"),
                         foreign_keys=[("trial_index", "trials", "trial_index")])
    db["trials"].create_index(["interaction"])
    db["events"].create_index(["kind"])


#: Version 2 (the whole handover cycle on the rig): each trial's cycle times and peak pull, and the
#: samples' cycle stage, force and pull. Literal, so that it means the same whatever the models become.
V2_TRIAL_COLUMNS = {"go_at": str, "hold_s": float, "release_s": float, "retract_end_s": float,
                    "peak_pull_n": float}
V2_SAMPLE_COLUMNS = {"stage": float, "force_x": float, "force_y": float, "force_z": float,
                     "pull": float}


def _add_cycle_columns(db: Database) -> None:
    for table, columns in (("trials", V2_TRIAL_COLUMNS), ("samples", V2_SAMPLE_COLUMNS)):
        existing = db[table].columns_dict
        for name, kind in columns.items():
            if name not in existing:  # a file created by this version has them already
                db[table].add_column(name, kind)


MIGRATIONS: dict[int, Callable[[Database], None]] = {1: _create_v1, 2: _add_cycle_columns}
SCHEMA_VERSION = max(MIGRATIONS)
