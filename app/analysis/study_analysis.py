"""What ``handover report`` computes from a study's tidy tables before it writes anything: the
sessions' status, the validation pairs and scores (Tables II–III), the survey (Table IV), the tests
of Sect. VI, the validation trajectories' distances (Fig. 4) and where each session's learning
ended."""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from app.analysis.cycle_times import cycle_table
from app.analysis.learning_stop import learning_table
from app.analysis.provenance import validation_blinding
from app.analysis.stats import StatTest, paper_tests
from app.analysis.tables import (
    session_status,
    survey_table,
    theta_star,
    validation_pairs,
    validation_scores,
)
from app.analysis.trajectories import validation_distances


@dataclass(frozen=True)
class StudyAnalysis:
    """Everything the report shows, computed from a study's tidy tables."""

    tables: dict[str, pd.DataFrame]
    status: pd.DataFrame
    pairs: pd.DataFrame
    scores: pd.DataFrame
    survey: pd.DataFrame
    tests: list[StatTest]
    distances: pd.DataFrame
    learning: pd.DataFrame  # per participant: where learning ended and why, ties (issue 40)
    cycle: pd.DataFrame  # per stage of the handover cycle: trials that reached it, time in it

    @classmethod
    def of(cls, tables: dict[str, pd.DataFrame]) -> StudyAnalysis:
        status = session_status(tables["participants"], tables["events"])
        blinding = validation_blinding(tables["trials"], tables["events"])
        status["validation_blinding"] = status["participant"].map(blinding).fillna("not recorded")
        pairs = validation_pairs(tables["trials"], tables["validation_ratings"])
        scores = validation_scores(pairs, theta_star(tables["learner_snapshots"]), status)
        survey = survey_table(tables["answers"], status)
        distances = validation_distances(tables["participants"], tables["trials"], tables["samples"])
        learning = learning_table(tables["participants"], tables["trials"], tables["events"])
        return cls(tables, status, pairs, scores, survey, paper_tests(scores, survey), distances,
                   learning, cycle_table(tables["events"]))
