"""The paper's tables from the tidy tables of a study (``session_store.export``), as DataFrames.

- :func:`session_status`: where each participant's session stands (complete or where it stopped);
- :func:`theta_star`: the learned θ* per participant, the last learner snapshot (docs/data.md);
- :func:`validation_pairs` and :func:`validation_scores`: Tables II–III (Sect. VI-A);
- :func:`survey_table`: Table IV (Sect. VI-B).

Each function takes the tables it needs as loaded by ``read_table`` (or ``load_study``) and returns a
new frame with one row per participant (per validation pair for :func:`validation_pairs`).

**Validation score** (Tables II–III): the share of a participant's rated validation pairs in which the
learned θ* was preferred. A pair rated "equal" is a pair in which θ* was *not* preferred: it stays in
the denominator. This is the paper's count as far as the paper shows it: with 4 pairs every score in
Tables II–III is a multiple of 25 %, which rules out dropping "equal" pairs (33 %, 67 %) or counting
them as half (12.5 % steps) for any participant who used "equal". The paper marks with * a score whose
missed pair compared two identical non-reactive controllers (Sect. VII); here a pair is flagged
``indistinct`` when the robot reached the handover point at practically the same time with both θ
(within :data:`INDISTINCT_ARRIVAL_S`), and a score gets * when one of its missed pairs is indistinct.
"""

from __future__ import annotations

import json

import pandas as pd

from app.protocol.plan import protocol_slots
from app.protocol.state import Step, replay
from app.protocol.study_config import StudyConfig
from session_store.models import Event
from session_store.vocabulary import question_ids, questions

#: Two validation trials whose robot arrivals differ by less than this are the same robot behaviour
#: to a person (10 control cycles at 500 Hz; people do not resolve timing differences this small).
INDISTINCT_ARRIVAL_S = 0.02
THETA_COLUMNS = ("theta_a", "theta_delta", "theta_k")
SCENARIOS = ("straightforward", "perturbed")


def study_configs(participants: pd.DataFrame) -> dict[str, StudyConfig]:
    """Each participant's study configuration (the ``config`` JSON of the participants table)."""
    return {row.participant: StudyConfig.model_validate_json(row.config)
            for row in participants.itertuples()}


def events_of(events: pd.DataFrame, code: str) -> list[Event]:
    """``code``'s events of the study's events table, in order, as the store gives them."""
    rows = events[events["participant"] == code].sort_values("seq")
    return [Event(seq=int(row.seq), at=row.at, actor=row.actor, kind=row.kind,
                  payload=json.loads(row.payload)) for row in rows.itertuples()]


def session_status(participants: pd.DataFrame, events: pd.DataFrame) -> pd.DataFrame:
    """Per participant: scenario, completed / planned interactions (without the learning ones an
    early stop skipped), and where the session stands.

    The state is rebuilt from the event log by the protocol's own replay (``app.protocol.state``),
    so "complete" means exactly what the session engine means by done.
    """
    rows = []
    for code, config in study_configs(participants).items():
        state = replay(protocol_slots(config), events_of(events, code))
        done = state.step is Step.DONE
        rows.append({"participant": code, "scenario": config.scenario.value,
                     "completed": state.completed, "planned": state.interactions,
                     "phase": state.phase.value, "waiting_for": None if done else state.step.value,
                     "complete": done})
    return pd.DataFrame(rows, columns=["participant", "scenario", "completed", "planned", "phase",
                                       "waiting_for", "complete"])


def theta_star(learner_snapshots: pd.DataFrame) -> pd.DataFrame:
    """θ* per participant: the last learner snapshot (with its posterior mean utility)."""
    last = learner_snapshots.sort_values("after_interaction").groupby("participant").tail(1)
    return last.rename(columns={f"theta_star_{n}": f"theta_{n}" for n in ("a", "delta", "k")})[
        ["participant", *THETA_COLUMNS, "utility_mean", "after_interaction"]].reset_index(drop=True)


def validation_pairs(trials: pd.DataFrame, validation_ratings: pd.DataFrame) -> pd.DataFrame:
    """One row per rated validation pair: θ* and the Sobol θ, the rating, who won, and whether the
    robot behaved the same with both (``indistinct``)."""
    done = trials[(trials["phase"] == "validation") & (trials["outcome"] == "completed")]
    learned = done[done["origin"] == "best"].set_index(["participant", "batch"])
    sobol = done[done["origin"] == "sobol"].set_index(["participant", "batch"])
    pairs = validation_ratings.set_index(["participant", "batch"])[["rating", "learned_preferred"]]
    columns = ["interaction", *THETA_COLUMNS, "robot_arrival_s"]
    for side, rows in (("learned", learned), ("sobol", sobol)):
        pairs = pairs.join(rows[columns].rename(columns=lambda c, s=side: f"{c}_{s}"))
    pairs["learned_first"] = pairs["interaction_learned"] < pairs["interaction_sobol"]
    gap = (pairs["robot_arrival_s_learned"] - pairs["robot_arrival_s_sobol"]).abs()
    pairs["indistinct"] = gap < INDISTINCT_ARRIVAL_S
    return pairs.reset_index()


def validation_scores(pairs: pd.DataFrame, stars: pd.DataFrame, status: pd.DataFrame) -> pd.DataFrame:
    """Tables II–III: per participant θ*, pairs won / lost / equal, and the validation score [%].

    ``pairs`` from :func:`validation_pairs`, ``stars`` from :func:`theta_star`, ``status`` from
    :func:`session_status`; every participant of ``status`` gets a row (NaN score without pairs).
    """
    won = pairs["learned_preferred"].fillna(False).astype(bool)
    lost = pairs["learned_preferred"].eq(False).fillna(False).astype(bool)
    counts = pd.DataFrame({
        "participant": pairs["participant"], "pairs": 1, "learned_preferred": won.astype(int),
        "sobol_preferred": lost.astype(int),
        "equal": pairs["learned_preferred"].isna().astype(int),
        "indistinct_missed": (~won & pairs["indistinct"].fillna(False).astype(bool)).astype(int),
    }).groupby("participant").sum()
    table = status[["participant", "scenario", "complete"]].merge(stars, on="participant", how="left")
    table = table.merge(counts, on="participant", how="left")
    count_columns = ["pairs", "learned_preferred", "sobol_preferred", "equal", "indistinct_missed"]
    table[count_columns] = table[count_columns].fillna(0).astype(int)
    table["score_pct"] = 100.0 * table["learned_preferred"] / table["pairs"].where(table["pairs"] > 0)
    return table


def survey_table(answers: pd.DataFrame, status: pd.DataFrame) -> pd.DataFrame:
    """Table IV: a column per question of the questionnaire, in its order, per participant; a
    numeric question's answers as numbers (Q1, Q3: 1–5), the others as words (Q2: Yes / No /
    Maybe)."""
    wide = answers.pivot(index="participant", columns="question", values="value")
    wide = wide.reindex(columns=question_ids())
    table = status[["participant", "scenario", "complete"]].merge(
        wide.reset_index(), on="participant", how="left")
    for question in questions():
        table[question.id] = (pd.to_numeric(table[question.id]).astype("Int64") if question.numeric
                              else table[question.id].astype("string"))
    return table
