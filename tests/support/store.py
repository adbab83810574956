"""Reading a participant database from a test beside the process that writes it, and comparing
what two sessions came to."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import NamedTuple

import numpy as np


def _read_only(path: Path) -> sqlite3.Connection:
    return sqlite3.connect(f"file:{path}?mode=ro", uri=True)


def events(path: Path) -> list[tuple[int, str, str]]:
    """``(seq, actor, kind)`` of the events written so far (none before the session exists);
    read-only, beside the writer."""
    try:
        with _read_only(path) as conn:
            return conn.execute("SELECT seq, actor, kind FROM events ORDER BY seq").fetchall()
    except sqlite3.Error:
        return []


def event_count(path: Path) -> int:
    """Events written so far (0 before the session exists); read-only, beside the writer."""
    return len(events(path))


class Progress(NamedTuple):
    """Where a session stands as its writer has committed it: interactions completed, and its
    latest event (kind and payload; None before the session exists)."""

    completed: int
    kind: str | None
    payload: dict


def progress(path: Path) -> Progress:
    """The session's :class:`Progress`, read-only beside the writer (a few rows, cheap to poll)."""
    try:
        with _read_only(path) as conn:
            completed = conn.execute("SELECT count(*) FROM trials WHERE outcome = 'completed'"
                                     ).fetchone()[0]
            last = conn.execute("SELECT kind, payload FROM events ORDER BY seq DESC LIMIT 1"
                                ).fetchone()
    except sqlite3.Error:
        return Progress(0, None, {})
    return Progress(completed, *(last[0], json.loads(last[1])) if last else (None, {}))


def session_outcome(path: Path) -> dict[str, list]:
    """What a session came to, table by table, keyed so that two sessions compare whatever their
    trial numbers: completed interactions with their θ, placements, comparisons, answers and
    validation ratings."""
    with sqlite3.connect(path) as conn:
        def rows(sql: str) -> list:
            return conn.execute(sql).fetchall()
        return {
            "completed trials": rows("SELECT interaction, theta_a, theta_delta, theta_k FROM trials "
                                     "WHERE outcome = 'completed' ORDER BY interaction"),
            "placements": rows("SELECT interaction, position, equal_to FROM placements "
                               "ORDER BY interaction"),
            "comparisons": rows("SELECT source, winner, loser FROM comparisons "
                                "ORDER BY source, winner, loser"),
            "answers": rows("SELECT question, value FROM answers ORDER BY question"),
            "validation": rows("SELECT interaction, rating FROM validation_ratings "
                               "ORDER BY interaction"),
        }


def assert_same_outcome(resumed: Path, whole: Path) -> None:
    """The session in ``resumed`` came to what the uninterrupted one in ``whole`` did: the same
    placements, comparisons, answers and ratings exactly, and the same interactions completed with
    the same θ. Across processes θ may differ in its last bits (SIMD reductions depend on memory
    alignment), which the acquisition optimiser can carry up to its own tolerance (seen: 2e-9
    relative), far below any physical meaning for a ∈ [1, 10], δ ∈ [-1, 1], k ∈ [0.01, 15]."""
    got, expected = session_outcome(resumed), session_outcome(whole)
    for table in sorted(expected, key=lambda name: name == "completed trials"):  # θ last
        if table == "completed trials":
            assert [row[0] for row in got[table]] == [row[0] for row in expected[table]]
            np.testing.assert_allclose(np.array(got[table])[:, 1:],
                                       np.array(expected[table])[:, 1:], rtol=1e-6)
        else:
            assert got[table] == expected[table], table
