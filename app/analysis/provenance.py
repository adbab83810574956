"""Who gave each answer, whose answers the report counts, and whether the validation was run blind.

Placements, hints, validation ratings and answers carry their origin (``actor``: participant,
simulated_participant or experimenter on the participant's behalf; empty in rows stored before
schema version 3, whose origin was not recorded, counted as the participant's). The report counts
per participant who gave each kind (:func:`answers_by`). Unless told ``--include-simulated`` it
leaves out a participant whose learning used the simulated participant's answers (their θ* is not a
person's), marked § wherever they appear, and a kept participant's simulated validation ratings and
answers; a study in which no person answered at all (a pilot, a demo, ``run-session --auto``) is
reported whole under a banner that says so (:class:`Counting`).

The validation is blind to the participant by design (the order within a pair is random, Sect. V-C)
and, by default, to the experimenter too: the dashboard hides the θ and origin of validation trials
unless ``handover serve --unblind``. Each session records the blinding of the dashboard that served
it (``validation_blinding_set``, at the first open and whenever a restart changes it);
:func:`validation_blinding` says, per participant, under which blinding its validation trials ran.
"""

from __future__ import annotations

import json
from collections.abc import Mapping

import pandas as pd
from pydantic import BaseModel

from app.protocol import events as ev
from app.protocol.entries import not_used_words
from session_store.vocabulary import Rater

#: The kinds of answer a participant gives: the table that stores them → the name of their columns.
ANSWER_KINDS = {"placements": "placements", "hints": "hints", "validation_ratings": "validation",
                "answers": "questionnaire"}
#: The kinds of answer the learner learns from (the initial and learning batches).
LEARNING_KINDS = ("placements", "hints")
#: Who gave an answer (its ``actor``) → the name of its column; None: not recorded (stored before
#: schema version 3), counted as the participant's.
RATER_COLUMNS: dict[str | None, str] = {Rater.PARTICIPANT.value: "participant",
                                        Rater.EXPERIMENTER.value: "experimenter",
                                        Rater.SIMULATED_PARTICIPANT.value: "simulated",
                                        None: "unrecorded"}
#: The mark of a participant whose learning used the simulated participant's answers.
SIMULATED_MARK = "§"
#: The tables whose simulated rows are left out of a kept participant's results by default.
RATED_TABLES = ("validation_ratings", "answers")
INCLUDE = "handover report --include-simulated"


def answers_by(tables: Mapping[str, pd.DataFrame], codes: list[str]) -> pd.DataFrame:
    """Per participant of ``codes``, how many answers of each kind (:data:`ANSWER_KINDS`) each
    rater gave: columns ``<kind>_<rater>`` (e.g. ``placements_simulated``, ``hints_experimenter``)
    and ``simulated_learning``: some placement or hint the learner learned from was the simulated
    participant's."""
    frame = pd.DataFrame({"participant": codes})
    for table, kind in ANSWER_KINDS.items():
        rows = tables[table]
        for rater, column in RATER_COLUMNS.items():
            given = rows[rows["actor"].isna() if rater is None else rows["actor"] == rater]
            frame[f"{kind}_{column}"] = frame["participant"].map(
                given.groupby("participant").size()).fillna(0).astype(int)
    frame["simulated_learning"] = sum(frame[f"{ANSWER_KINDS[k]}_simulated"]
                                      for k in LEARNING_KINDS) > 0
    return frame


def answers_text(row: pd.Series, kind: str) -> str:
    """Who gave one kind of a participant's answers, e.g. "2 participant, 1 experimenter, 3
    simulated" ("—": none)."""
    parts = [f"{row[f'{kind}_{column}']} {column}" for column in RATER_COLUMNS.values()
             if row[f"{kind}_{column}"]]
    return ", ".join(parts) or "—"


def _simulated_words(row: pd.Series) -> str:
    """How much of a participant's learning the simulated participant answered, e.g. "3 of 6
    placements by the simulated participant"."""
    parts = []
    for kind in (ANSWER_KINDS[k] for k in LEARNING_KINDS):
        simulated = int(row[f"{kind}_simulated"])
        if simulated:
            given = sum(int(row[f"{kind}_{c}"]) for c in RATER_COLUMNS.values())
            parts.append(f"{simulated} of {given} {kind} by the simulated participant")
    return ", ".join(parts)


def answers_not_used(events: pd.DataFrame) -> list[str]:
    """Every answer recorded as not used (two at once: :mod:`app.protocol.entries`), as "P03:
    Not used: the participant's hint about handover 7 (sooner) came after …"."""
    rows = events[events["kind"] == "entry_not_used"].sort_values(["participant", "seq"])
    return [f"{row.participant}: " + not_used_words(ev.EntryNotUsed.model_validate(
        {**json.loads(row.payload), "seq": int(row.seq), "at": row.at, "actor": row.actor}))
        for row in rows.itertuples()]


class Counting(BaseModel):
    """Whose answers the report counted, and which participants it left out of the paper's
    tables (Tables II–IV and the tests)."""

    include_simulated: bool  # asked for (--include-simulated)
    simulated_study: bool  # every answer of the study is the simulated participant's
    simulated_learning: dict[str, str]  # participant → how much of its learning was simulated
    simulated_rows: int  # validation ratings and answers by the simulated participant, not counted
    unrecorded: int  # answers of unrecorded origin (counted as the participants')

    @property
    def counts_simulated(self) -> bool:
        """Whether the simulated participant's answers count (asked for, or a simulated study)."""
        return self.include_simulated or self.simulated_study

    @property
    def marked(self) -> list[str]:
        """The participants marked §: those whose learning used simulated answers, unless every
        answer of the study is the simulated participant's (the banner says so of them all)."""
        return [] if self.simulated_study else list(self.simulated_learning)

    @property
    def left_out(self) -> list[str]:
        """The participants left out of the paper's tables: their learning used simulated
        answers, and the report does not count those."""
        return [] if self.counts_simulated else list(self.simulated_learning)

    def problem(self, code: str) -> str:
        """What the report did with ``code``, whose learning used simulated answers."""
        done = (f"included by {INCLUDE.removeprefix('handover report ')}"
                if self.counts_simulated else
                f"left out of Tables II–IV and the tests ({INCLUDE} includes it)")
        return (f"learning used the simulated participant's answers "
                f"({self.simulated_learning[code]}); {done}")

    def text(self) -> str:
        if self.simulated_study:
            return ("Simulated study: every answer in it (placements, hints, validation ratings, "
                    "questionnaire) was given by the simulated participant — a pilot, a demo or "
                    "run-session --auto, not people. It is reported whole, so that the pipeline "
                    "can be checked; nothing in it is a result about people.")
        marked = ", ".join(self.simulated_learning)
        if self.include_simulated:
            head = ("Answers counted: the participants', the experimenter's entries on their "
                    "behalf and, by --include-simulated, the simulated participant's"
                    + (f"; marked {SIMULATED_MARK}, the participants whose learning used them: "
                       f"{marked}." if marked else "."))
        else:
            head = "Answers counted: the participants' own and the experimenter's entries on " \
                   "their behalf."
            if marked:
                head += (f" The participants whose learning used the simulated participant's "
                         f"answers are marked {SIMULATED_MARK} and left out of Tables II–IV and "
                         f"the tests: {marked}.")
            if self.simulated_rows:
                head += (f" {self.simulated_rows} validation ratings and answers by the simulated "
                         f"participant are left out.")
            if marked or self.simulated_rows:
                head += f" ({INCLUDE} counts them.)"
        if self.unrecorded:
            head += (f" {self.unrecorded} answers of unrecorded origin (stored before provenance "
                     "was recorded, schema version < 3) are counted as the participants'.")
        return head


def counted_answers(tables: Mapping[str, pd.DataFrame], answered: pd.DataFrame,
                    include_simulated: bool) -> tuple[dict[str, pd.DataFrame], Counting]:
    """``tables`` as the report counts them, and what it counted. ``answered``:
    :func:`answers_by`. Unless the simulated participant's answers count (``include_simulated``,
    or a study in which no person answered), a kept participant's simulated validation ratings
    and answers are left out (a participant whose learning was simulated is left out whole, by
    the analysis: :attr:`Counting.left_out`)."""
    columns = [f"{kind}_{c}" for kind in ANSWER_KINDS.values() for c in RATER_COLUMNS.values()]
    simulated = [c for c in columns if c.endswith("_simulated")]
    by_people = int(answered[[c for c in columns if c not in simulated]].to_numpy().sum())
    by_simulation = int(answered[simulated].to_numpy().sum())
    marked = answered[answered["simulated_learning"]]
    counting = Counting(
        include_simulated=include_simulated, simulated_study=by_people == 0 and by_simulation > 0,
        simulated_learning={row["participant"]: _simulated_words(row)
                            for _, row in marked.iterrows()},
        simulated_rows=0, unrecorded=int(answered[[c for c in columns
                                                   if c.endswith("_unrecorded")]].to_numpy().sum()))
    kept = dict(tables)
    if counting.counts_simulated:
        return kept, counting
    rows = 0
    for table in RATED_TABLES:
        frame = tables[table]
        by_simulation_row = (frame["actor"] == Rater.SIMULATED_PARTICIPANT.value).fillna(False)
        rows += int((by_simulation_row & ~frame["participant"].isin(counting.left_out)).sum())
        kept[table] = frame[~by_simulation_row.astype(bool)].reset_index(drop=True)
    return kept, counting.model_copy(update={"simulated_rows": rows})


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
