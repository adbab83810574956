"""A stored trial's samples as the recorder's columns: for a replay on the dashboard and for the
trial's safety record (app/protocol/safety_record.py).

The store keeps one row per control cycle with vectors flattened to ``name_x`` … ``name_z`` (the joint
angles to ``q_0`` … ``q_5``) and NaN as NULL (:mod:`session_store.schema`); here they become the
recorder's own columns again (groups of shape (n, width), NULL back to NaN), so a replay draws exactly
what the loop recorded.
"""

from __future__ import annotations

import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any

import numpy as np

from robot_io.control.recorder import COLUMNS
from session_store.file_check import connect_read_only
from session_store.schema import column_suffixes, sample_column_names


def stored_rows(samples: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """The recorder's columns of a trial's stored sample rows (in cycle order)."""
    def column(name: str) -> np.ndarray:
        return np.array([np.nan if row[name] is None else row[name] for row in samples], dtype=float)

    rows: dict[str, np.ndarray] = {}
    for name, width, _ in COLUMNS:
        if width == 1:
            rows[name] = column(name)
        else:
            rows[name] = np.stack([column(f"{name}_{suffix}") for suffix in column_suffixes(width)],
                                  axis=1) if samples else np.zeros((0, width))
    return rows


def read_samples(path: Path, trial_indices: list[int]) -> dict[int, dict[str, np.ndarray]]:
    """The recorder's columns of the trials ``trial_indices`` of the database at ``path``, read
    without writing (``handover doctor``); a file of a schema without some columns gives them NaN."""
    with closing(connect_read_only(path)) as conn:
        conn.row_factory = sqlite3.Row
        empty = dict.fromkeys(sample_column_names())

        def read(index: int) -> list[dict[str, Any]]:
            rows = conn.execute("SELECT * FROM samples WHERE trial_index = ? ORDER BY cycle", [index])
            return [{**empty, **dict(row)} for row in rows]

        return {index: stored_rows(read(index)) for index in trial_indices}

