"""The participant database's tables and their migrations.

The schema version is SQLite's ``PRAGMA user_version``. ``MIGRATIONS[n]`` takes a database from
version n − 1 to n; opening a file runs the missing ones in order, each in its own transaction.
Every version is written out literally (version 1 in :data:`V1_TABLES`, later ones as the columns
their migration adds), never derived from the models: a model that gains a field needs a migration,
and ``tests/session_store/test_schema.py`` checks that the models and the latest version agree.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Callable, Mapping
from enum import Enum

from pydantic import BaseModel

from robot_io.control.recorder import COLUMNS as SAMPLE_COLUMNS
from session_store.database import Database
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

AXES = ("x", "y", "z")


def column_suffixes(width: int) -> tuple[str, ...]:
    """How a sample column group of ``width`` is flattened: none for a scalar, ``x``, ``y``, ``z``
    for a 3-vector, ``0`` … ``width − 1`` otherwise (the joint angles q_0 … q_5)."""
    if width == 1:
        return ()
    return AXES if width == len(AXES) else tuple(str(i) for i in range(width))


def sample_columns() -> dict[str, str]:
    """Flat columns of a trial sample row and their meaning: vectors become ``name_x`` … ``name_z``,
    other groups ``name_0`` … (:func:`column_suffixes`)."""
    columns = {}
    for name, width, meaning in SAMPLE_COLUMNS:
        if width == 1:
            columns[name] = meaning
        for suffix in column_suffixes(width):
            columns[f"{name}_{suffix}"] = f"{meaning}, {suffix}"
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
    "hints": (HintRow, "trial_index"),
    "learner_snapshots": (LearnerSnapshotRow, "after_interaction"),
    "events": (Event, "seq"),
}


#: Version 1, frozen: the tables as the first release created them, written out literally so that
#: changing a model never changes what a version-1 file is. Later columns come by migration.
V1_TABLES: dict[str, tuple[dict[str, type], str | tuple[str, ...]]] = {
    "participant": ({"code": str, "created_at": str, "config": str}, "code"),
    "trials": ({"trial_index": int, "interaction": int, "attempt": int, "phase": str, "batch": int,
                "position": int, "theta_a": float, "theta_delta": float, "theta_k": float,
                "origin": str, "hand_seed": int, "started_at": str, "ended_at": str, "outcome": str,
                "reason": str, "robot_arrival_s": float, "hand_arrival_s": float,
                "arrival_gap_s": float, "peak_speed_mps": float, "max_tau": float,
                "deadline_misses": int}, "trial_index"),
    "placements": ({"trial_index": int, "interaction": int, "batch": int, "position": float,
                    "equal_to": int, "placed_at": str}, "trial_index"),
    "comparisons": ({"batch": int, "source": int, "winner": int, "loser": int},
                    ("source", "winner", "loser")),
    "validation_ratings": ({"batch": int, "trial_index": int, "interaction": int, "rating": str,
                            "learned_preferred": int, "rated_at": str}, "trial_index"),
    "answers": ({"question": str, "value": str, "answered_at": str}, "question"),
    "learner_snapshots": ({"after_interaction": int, "theta_star_a": float,
                           "theta_star_delta": float, "theta_star_k": float,
                           "utility_mean": float, "fit_failed": int, "message": str,
                           "n_points": int, "n_comparisons": int, "state": str,
                           "created_at": str}, "after_interaction"),
    "events": ({"seq": int, "at": str, "actor": str, "kind": str, "payload": str}, "seq"),
}
V1_SAMPLE_COLUMNS: tuple[str, ...] = (
    "t", "s", "tau", "x_x", "x_y", "x_z", "xd_x", "xd_y", "xd_z", "hand_x", "hand_y", "hand_z",
    "hand_t", "d", "d_filtered", "d_rate", "sigma_d", "sigma_j", "c_t", "c_s_x", "c_s_y", "c_s_z",
    "commanded_x", "commanded_y", "commanded_z", "measured_x", "measured_y", "measured_z",
    "limited", "compute_s", "lateness_s")


def _create_v1(db: Database) -> None:
    for table, (columns, pk) in V1_TABLES.items():
        db.table(table).create(columns, pk=pk)
    samples = {"trial_index": int, "cycle": int} | {name: float for name in V1_SAMPLE_COLUMNS}
    db.table("samples").create(samples, pk=("trial_index", "cycle"),
                         foreign_keys=[("trial_index", "trials", "trial_index")])
    db.table("trials").create_index(["interaction"])
    db.table("events").create_index(["kind"])


def _add_columns(db: Database, table: str, columns: Mapping[str, type]) -> None:
    existing = db[table].columns_dict
    for name, kind in columns.items():
        if name not in existing:  # files made when version 1 was built from the models have them
            db.table(table).add_column(name, kind)


#: Version 2 (the whole handover cycle on the rig): each trial's cycle times and peak pull, and the
#: samples' cycle stage, force and pull. Literal, so that it means the same whatever the models become.
V2_TRIAL_COLUMNS = {"go_at": str, "hold_s": float, "release_s": float, "retract_end_s": float,
                    "peak_pull_n": float}
V2_SAMPLE_COLUMNS = {"stage": float, "force_x": float, "force_y": float, "force_z": float,
                     "pull": float}


def _add_cycle_columns(db: Database) -> None:
    _add_columns(db, "trials", V2_TRIAL_COLUMNS)
    _add_columns(db, "samples", V2_SAMPLE_COLUMNS)


#: Version 3 (provenance): who made each placement, validation rating and answer — participant,
#: simulated_participant or experimenter. Rows stored before it keep an empty (unknown) origin.
V3_PROVENANCE_TABLES = ("placements", "validation_ratings", "answers")


def _add_provenance(db: Database) -> None:
    for table in V3_PROVENANCE_TABLES:
        _add_columns(db, table, {"actor": str})


#: Version 4 (the arm's joints): each sample's joint angles as read from the arm [rad], base …
#: wrist 3. Empty (NULL) for an arm that does not report them and in rows stored before it.
V4_SAMPLE_COLUMNS = {f"q_{i}": float for i in range(6)}


def _add_joint_columns(db: Database) -> None:
    _add_columns(db, "samples", V4_SAMPLE_COLUMNS)


#: Version 5 (coactive hints, ``[protocol] coactive``): one row per hint given after a placement.
V5_HINT_COLUMNS = {"trial_index": int, "interaction": int, "batch": int, "hint": str,
                   "step": float, "hinted_a": float, "hinted_delta": float, "hinted_k": float,
                   "given_at": str, "actor": str}


def _add_hints(db: Database) -> None:
    if "hints" not in db.table_names():
        db.table("hints").create(V5_HINT_COLUMNS, pk="trial_index")


#: Version 6 (the safety record, issue 47): each trial's closest tool–hand distance, the tool's
#: speed and closing speed with the hand near, pull to open, the longest contact, and the parameters
#: they were taken with. Empty (NULL) in trials stored before it.
V6_TRIAL_COLUMNS = {"min_distance_m": float, "speed_near_mps": float, "closing_speed_mps": float,
                    "pull_to_open_s": float, "longest_contact_s": float, "near_radius_m": float,
                    "contact_pull_n": float}


def _add_safety_record(db: Database) -> None:
    _add_columns(db, "trials", V6_TRIAL_COLUMNS)


MIGRATIONS: dict[int, Callable[[Database], None]] = {1: _create_v1, 2: _add_cycle_columns,
                                                     3: _add_provenance, 4: _add_joint_columns,
                                                     5: _add_hints, 6: _add_safety_record}
SCHEMA_VERSION = max(MIGRATIONS)
