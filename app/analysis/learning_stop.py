"""Per participant, where learning ended and why, and the ties and hints the learner used (issue 40).

With a stopping rule (``[protocol] stop_when_settled`` or ``stop_when_no_gain``; ``preset =
"short"`` sets the first) a session may end learning after a batch (a ``learning_stopped`` event
records the signal and the reason); otherwise it runs the paper's fixed schedule. With ``[learner]
ties = "model"`` each "equal" placement of the initial and learning batches is information for the
learner; with "drop" (the paper) it is not. With ``[protocol] coactive`` the participant may give a
hint after each placement (a ``hint_given`` event; none when they said nothing should change).
"""

from __future__ import annotations

import pandas as pd

from app.analysis.tables import events_of, study_configs
from app.protocol.learning_words import learning_end, recorded_stop, rule_words
from app.protocol.plan import protocol_slots
from app.protocol.state import replay
from session_store.vocabulary import Phase

COLUMNS = ["participant", "scenario", "learning_interactions", "schedule_interactions",
           "learning_ended", "why", "stopping_rule", "ties_placed", "ties", "hints_given",
           "hints_asked"]
LEARNED_PHASES = (Phase.INITIAL.value, Phase.LEARNING.value)


def learning_table(participants: pd.DataFrame, trials: pd.DataFrame,
                   events: pd.DataFrame) -> pd.DataFrame:
    """One row per participant: the initial and learning interactions completed, those of the
    fixed schedule, how learning ended — early, at the schedule's end, interrupted or not started
    (:func:`~app.protocol.learning_words.learning_end`) — and why, the stopping rule in words, the
    "equal" placements made there and what the learner did with them (``ties``: drop or model),
    and the coactive hints given of those asked for (both 0 without ``coactive``)."""
    rows = []
    for code, config in study_configs(participants).items():
        log = events_of(events, code)
        state = replay(protocol_slots(config), log)
        done = trials[(trials["participant"] == code) & (trials["outcome"] == "completed")
                      & trials["phase"].isin(LEARNED_PHASES)]
        placed = [e.payload for e in log if e.kind == "placement_made"]
        hints = [e.payload for e in log if e.kind == "hint_given"]
        paused = next((e.payload.get("reason", "") for e in reversed(log) if e.kind == "paused"),
                      None) if state.paused else None
        rule = config.stopping_rule()
        ended, why = learning_end(state, config, recorded_stop(log), paused)
        rows.append({"participant": code, "scenario": config.scenario.value,
                     "learning_interactions": len(done),
                     "schedule_interactions": config.initial_trials
                     + config.learning_batches * config.batch_size,
                     "learning_ended": ended, "why": why,
                     "stopping_rule": "none" if rule is None else rule_words(rule),
                     "ties_placed": sum(p.get("equal_to") is not None for p in placed),
                     "ties": config.ties,
                     "hints_given": sum(h.get("hint") is not None for h in hints),
                     "hints_asked": len(hints)})
    return pd.DataFrame(rows, columns=COLUMNS)
