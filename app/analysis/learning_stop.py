"""Per participant, where learning ended and why, and the ties and hints the learner used (issue 40).

With a stopping rule (``[protocol] stop_when_settled`` or ``stop_when_no_gain``; ``preset =
"short"`` sets the first) a session may end learning after a batch (a ``learning_stopped`` event
records the signal and the reason); otherwise it runs the paper's fixed schedule. With ``[learner]
ties = "model"`` each "equal" placement of the initial and learning batches is information for the
learner; with "drop" (the paper) it is not. With ``[protocol] coactive`` the participant may give a
hint after each placement (a ``hint_given`` event; none when they said nothing should change).
"""

from __future__ import annotations

import json

import pandas as pd

from app.analysis.tables import study_configs
from app.protocol.stopping import rule_words
from session_store.vocabulary import Phase

COLUMNS = ["participant", "scenario", "learning_interactions", "schedule_interactions",
           "learning_ended", "why", "stopping_rule", "ties_placed", "ties", "hints_given",
           "hints_asked"]
LEARNED_PHASES = (Phase.INITIAL.value, Phase.LEARNING.value)


def learning_table(participants: pd.DataFrame, trials: pd.DataFrame,
                   events: pd.DataFrame) -> pd.DataFrame:
    """One row per participant: the initial and learning interactions completed, those of the
    fixed schedule, whether learning ended early and why, the "equal" placements made there and
    what the learner did with them (``ties``: drop or model), and the coactive hints given of those
    asked for (both 0 without ``coactive``)."""
    stops = events[events["kind"] == "learning_stopped"]
    placed = events[events["kind"] == "placement_made"]
    hinted = events[events["kind"] == "hint_given"]
    rows = []
    for code, config in study_configs(participants).items():
        done = trials[(trials["participant"] == code) & (trials["outcome"] == "completed")
                      & trials["phase"].isin(LEARNED_PHASES)]
        stop = stops[stops["participant"] == code]
        payloads = [json.loads(p) for p in placed.loc[placed["participant"] == code, "payload"]]
        hints = [json.loads(p) for p in hinted.loc[hinted["participant"] == code, "payload"]]
        schedule = config.initial_trials + config.learning_batches * config.batch_size
        rule = config.stopping_rule()
        why = (json.loads(stop["payload"].iloc[-1])["reason"] if not stop.empty
               else "the fixed schedule" + ("" if rule is not None else " (no stopping rule)"))
        rows.append({"participant": code, "scenario": config.scenario.value,
                     "learning_interactions": len(done), "schedule_interactions": schedule,
                     "learning_ended": "early" if not stop.empty else "at the schedule's end",
                     "why": why, "stopping_rule": "none" if rule is None else rule_words(rule),
                     "ties_placed": sum(p.get("equal_to") is not None
                                                    for p in payloads),
                     "ties": config.ties,
                     "hints_given": sum(h.get("hint") is not None for h in hints),
                     "hints_asked": len(hints)})
    return pd.DataFrame(rows, columns=COLUMNS)
