"""Whose ratings the report counts, and whether the validation was run blind.

Validation ratings and answers carry their origin (``actor``: participant, simulated_participant or
experimenter on the participant's behalf; empty in rows stored before schema version 3, whose
origin was not recorded). The report leaves the simulated participant's out unless told to include
them, and says which it counted.

The validation is blind to the participant by design (the order within a pair is random, Sect. V-C)
and, by default, to the experimenter too: the dashboard hides the θ and origin of validation trials
unless ``handover serve --unblind``. Each session records the blinding of the dashboard that served
it (``validation_blinding_set``, at the first open and whenever a restart changes it);
:func:`validation_blinding` says, per participant, under which blinding its validation trials ran.
"""

from __future__ import annotations

import json

import pandas as pd
from pydantic import BaseModel

from session_store.vocabulary import Rater

#: The report's tables whose rows are ratings with an origin.
RATED_TABLES = ("validation_ratings", "answers")


class CountedRatings(BaseModel):
    """Which ratings the report counted."""

    include_simulated: bool
    simulated: int  # rows by the simulated participant (left out unless included)
    unrecorded: int  # rows of unrecorded origin (counted as the participant's)

    def text(self) -> str:
        if self.include_simulated:
            head = (f"Ratings counted: the participants' and the simulated participant's "
                    f"({self.simulated} validation ratings and answers by the simulated "
                    "participant included by --include-simulated).")
        else:
            head = (f"Ratings counted: the participants' own; {self.simulated} validation ratings "
                    "and answers by the simulated participant are left out (handover report "
                    "--include-simulated counts them).")
        if self.unrecorded:
            head += (f" {self.unrecorded} of unrecorded origin (stored before provenance was "
                     "recorded, schema version < 3) are counted as the participants'.")
        return head


def counted_ratings(tables: dict[str, pd.DataFrame], include_simulated: bool
                    ) -> tuple[dict[str, pd.DataFrame], CountedRatings]:
    """``tables`` with the simulated participant's ratings left out (unless ``include_simulated``),
    and what was counted."""
    simulated = unrecorded = 0
    kept = dict(tables)
    for table in RATED_TABLES:
        if table not in tables:
            continue
        frame = tables[table]
        by_simulation = frame["actor"] == Rater.SIMULATED_PARTICIPANT.value
        simulated += int(by_simulation.fillna(False).sum())
        unrecorded += int(frame["actor"].isna().sum())
        if not include_simulated:
            kept[table] = frame[~by_simulation.fillna(False).astype(bool)].reset_index(drop=True)
    return kept, CountedRatings(include_simulated=include_simulated, simulated=simulated,
                                unrecorded=unrecorded)


#: The event that records the dashboard's blinding (app.protocol.events.ValidationBlindingSet).
BLINDING_EVENT = "validation_blinding_set"


def _blinding_text(shown: list[bool | None]) -> str:
    """How a participant's validation trials were shown, one value per trial (None: unrecorded)."""
    if not shown:
        return "no validation trial yet"
    blind = sum(value is True for value in shown)
    if blind == len(shown):
        return "blind"
    if None in shown:  # run headless (no dashboard), or stored before serve recorded it
        return f"not recorded for {shown.count(None)} of {len(shown)} validation trials"
    if blind == 0:
        return "not blind (serve --unblind)"
    return f"partly blind: {blind} of {len(shown)} validation trials (serve --unblind for the rest)"


def validation_blinding(trials: pd.DataFrame, events: pd.DataFrame) -> dict[str, str]:
    """Per participant, whether the dashboard hid the θ and origin of each validation trial when it
    started: "blind", "not blind", "partly blind: n of N …", or "not recorded …" (sessions run
    headless or stored before the blinding was recorded)."""
    validation = trials[trials["phase"] == "validation"]
    result = {}
    for code, log in events.sort_values("seq").groupby("participant"):
        trial_indices = set(validation.loc[validation["participant"] == code, "trial_index"])
        blind, shown = None, []
        for row in log.itertuples():
            if row.kind == BLINDING_EVENT:
                blind = json.loads(row.payload)["blind"]
            elif row.kind == "trial_started" and json.loads(row.payload)["trial_index"] in trial_indices:
                shown.append(blind)
        result[code] = _blinding_text(shown)
    return result


def not_blind(status: pd.DataFrame) -> dict[str, str]:
    """The participants whose validation trials were not all shown blind, and how they were
    (``status``: the report's sessions, with :func:`validation_blinding`'s column)."""
    shown = status.set_index("participant")["validation_blinding"]
    return {code: text for code, text in shown.items()
            if text.startswith(("not blind", "partly blind"))}
