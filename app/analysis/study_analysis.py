"""What ``handover report`` computes from a study's tidy tables before it writes anything: who gave
the answers and which of them count (:mod:`app.analysis.provenance`), the sessions' status, the
validation pairs and scores (Tables II–III), the survey (Table IV), the tests of Sect. VI, the
validation trajectories' distances (Fig. 4) and where each session's learning ended."""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from app.analysis.cycle_times import cycle_table
from app.analysis.learning_stop import learning_table
from app.analysis.provenance import Counting, answers_by, counted_answers, validation_blinding
from app.analysis.stats import StatTest, paper_tests
from app.analysis.study_design import StudyDesign, study_design
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

    tables: dict[str, pd.DataFrame]  # as counted (the simulated answers left out, unless counted)
    counting: Counting
    design: StudyDesign  # the study plan, the groups as they ran, the deviations
    status: pd.DataFrame
    pairs: pd.DataFrame
    scores: pd.DataFrame
    survey: pd.DataFrame
    tests: list[StatTest]
    distances: pd.DataFrame
    #: per participant: where learning ended and why, ties (issue 40), who gave the answers
    learning: pd.DataFrame
    cycle: pd.DataFrame  # per stage of the handover cycle: trials that reached it, time in it

    @classmethod
    def of(cls, tables: dict[str, pd.DataFrame], include_simulated: bool = False) -> StudyAnalysis:
        """The analysis of ``tables`` (``load_study``'s, with placements and hints); the simulated
        participant's answers count with ``include_simulated`` or in a simulated study, else the
        participants whose learning used them are left out of Tables II–IV and the tests."""
        status = session_status(tables["participants"], tables["events"])
        answered = answers_by(tables, status["participant"].tolist())
        tables, counting = counted_answers(tables, answered, include_simulated)
        marked = status["participant"].map(answered.set_index("participant")["simulated_learning"])
        status["simulated_learning"] = marked.astype(bool)
        blinding = validation_blinding(tables["trials"], tables["events"])
        status["validation_blinding"] = status["participant"].map(blinding).fillna("not recorded")
        pairs = validation_pairs(tables["trials"], tables["validation_ratings"])
        kept = status[~status["participant"].isin(counting.left_out)]
        simulated = status.set_index("participant")["simulated_learning"]
        scores = validation_scores(pairs, theta_star(tables["learner_snapshots"]), kept)
        survey = survey_table(tables["answers"], kept)
        for frame in (scores, survey):  # beside "complete", before the numbers
            frame.insert(frame.columns.get_loc("complete") + 1, "simulated_learning",
                         frame["participant"].map(simulated).astype(bool))
        distances = validation_distances(tables["participants"], tables["trials"], tables["samples"])
        learning = learning_table(tables["participants"], tables["trials"], tables["events"]).merge(
            answered, on="participant")
        design = study_design(tables["participants"])
        return cls(tables, counting, design, status, pairs, scores, survey,
                   paper_tests(scores, survey, design.persons), distances, learning,
                   cycle_table(tables["events"]))
