"""Whose ratings the report counts: the participants' own by default.

Validation ratings and answers carry their origin (``actor``: participant, simulated_participant or
experimenter on the participant's behalf; empty in rows stored before schema version 3, whose
origin was not recorded). The report leaves the simulated participant's out unless told to include
them, and says which it counted.
"""

from __future__ import annotations

import pandas as pd
from pydantic import BaseModel

from app.protocol.vocabulary import Rater

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
                    "and answers by the simulated participant are left out (`handover report "
                    "--include-simulated` counts them).")
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
