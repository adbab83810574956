"""What the event log implies for the tables derived from it, and where the stored tables differ.

The event log is the truth (``handover doctor``): every row of ``trials`` (which attempt of which
interaction, its θ, its outcome, its safety record), ``placements``, ``comparisons``,
``validation_ratings`` and ``answers`` and ``hints`` was written in the transaction of the event
that records it. So the rows can be rebuilt from the events alone, and a row that differs from them,
is missing, or has no event was changed after it was written (an edit, a half-restored copy, a tool
that wrote the tables).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from session_store.models import Event, SafetyRecord

Key = int | str | tuple[int, int, int]
Rows = dict[Key, dict[str, Any]]

#: The fields of each table the events determine, by table; the key names the row.
FIELDS: dict[str, tuple[str, ...]] = {
    "trials": ("interaction", "attempt", "theta_a", "theta_delta", "theta_k", "outcome", "reason",
               *SafetyRecord.model_fields),
    "placements": ("trial_index", "position", "equal_to"),
    "comparisons": (),
    "validation_ratings": ("trial_index", "rating"),
    "answers": ("value",),
    "hints": ("trial_index", "hint", "hinted_a", "hinted_delta", "hinted_k"),
}
#: How a stored row's key is read, by table.
KEYS = {"trials": lambda r: r["trial_index"], "placements": lambda r: r["interaction"],
        "comparisons": lambda r: (r["source"], r["winner"], r["loser"]),
        "validation_ratings": lambda r: r["interaction"], "answers": lambda r: r["question"],
        "hints": lambda r: r["interaction"]}


def implied_rows(events: Iterable[Event]) -> dict[str, Rows]:
    """Each derived table's rows (the fields of :data:`FIELDS`) as the events record them. A trial
    has the θ planned for its interaction when it started; a validation rating is of the trial that
    completed its interaction."""
    rows: dict[str, Rows] = {table: {} for table in FIELDS}
    planned: dict[int, tuple[float, float, float]] = {}
    completed: dict[int, int] = {}  # interaction → trial_index
    for event in events:
        p = event.payload
        if event.kind == "theta_planned":
            planned[p["interaction"]] = (p["a"], p["delta"], p["k"])
        elif event.kind == "trial_started":
            a, delta, k = planned.get(p["interaction"], (None, None, None))
            rows["trials"][p["trial_index"]] = {
                "interaction": p["interaction"], "attempt": p["attempt"], "theta_a": a,
                "theta_delta": delta, "theta_k": k, "outcome": None, "reason": None,
                **dict.fromkeys(SafetyRecord.model_fields)}
        elif event.kind == "trial_ended" and p["trial_index"] in rows["trials"]:
            trial = rows["trials"][p["trial_index"]]
            trial.update(outcome=p["outcome"], reason=p.get("reason"), **(p.get("safety") or {}))
            if p["outcome"] == "completed":
                completed[trial["interaction"]] = p["trial_index"]
        elif event.kind == "placement_made":
            rows["placements"][p["interaction"]] = {
                "trial_index": p["trial_index"], "position": p["position"],
                "equal_to": p.get("equal_to")}
            for winner, loser in p["comparisons"]:
                rows["comparisons"][(p["interaction"], winner, loser)] = {}
        elif event.kind == "validation_rated":
            rows["validation_ratings"][p["interaction"]] = {
                "trial_index": completed.get(p["interaction"]), "rating": p["rating"]}
        elif event.kind == "answer_given":
            rows["answers"][p["question"]] = {"value": p["value"]}
        elif event.kind == "hint_given":
            hinted = p.get("hinted") or {}
            rows["hints"][p["interaction"]] = {
                "trial_index": p["trial_index"], "hint": p.get("hint"),
                "hinted_a": hinted.get("a"), "hinted_delta": hinted.get("delta"),
                "hinted_k": hinted.get("k")}
    return rows


def _same(stored: Any, implied: Any) -> bool:
    if isinstance(stored, float) and isinstance(implied, float):
        return math.isclose(stored, implied, rel_tol=1e-12, abs_tol=1e-12)
    return stored == implied


def _name(table: str, key: Key) -> str:
    if table == "trials":
        return f"trial {key}"
    if table == "comparisons":
        assert isinstance(key, tuple), "a comparison is keyed by (source, winner, loser)"
        source, winner, loser = key
        return f"comparison {winner} over {loser} (from interaction {source}'s placement)"
    if table == "answers":
        return f"answer to {key}"
    if table == "hints":
        return f"hint about interaction {key}"
    return f"interaction {key}"


def differences(stored: dict[str, list[dict[str, Any]]], events: Iterable[Event]) -> list[str]:
    """Where the stored tables differ from what the events imply, one sentence each: a row the
    events record that the table lacks, a row of the table no event records, a field that differs."""
    problems = []
    for table, implied in implied_rows(events).items():
        rows = {KEYS[table](row): row for row in stored.get(table, [])}
        for key in implied.keys() - rows.keys():
            problems.append(f"{table}: {_name(table, key)} is in the event log but not in the table")
        for key in rows.keys() - implied.keys():
            problems.append(f"{table}: {_name(table, key)} is in the table but no event records it")
        for key in implied.keys() & rows.keys():
            for field in FIELDS[table]:
                stored_value = rows[key].get(field)  # None: a column of a later schema version
                if not _same(stored_value, implied[key][field]):
                    problems.append(f"{table}: {_name(table, key)} has {field} = "
                                    f"{stored_value!r} in the table, {implied[key][field]!r} "
                                    "in the event log")
    return sorted(problems)
