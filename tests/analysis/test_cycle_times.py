"""The report's table of the handover cycle (app.analysis.cycle_times): the time each trial spent in
a stage is from its trial_stage event to the trial's next one (or its end); the stages come in the
cycle's order, a stage the records name that the cycle no longer has after them, still counted."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import pandas as pd
import pytest
from support.engine import short_config

from app.analysis.cycle_times import cycle_table
from app.protocol import events as ev
from app.protocol.plan import protocol_slots
from app.protocol.state import replay
from robot_io.control.stages import PAPER_CYCLE
from session_store.vocabulary import Actor

START = datetime(2026, 11, 28, 12, 0, tzinfo=UTC)


def events(*trials: list[tuple[str, float]]) -> pd.DataFrame:
    """Stored events of one participant: per trial its stages (name, seconds after its start)
    and its end ("end")."""
    rows, seq = [], 0
    for index, stages in enumerate(trials, 1):
        for stage, seconds in stages:
            seq += 1
            at = (START + timedelta(minutes=index, seconds=seconds)).isoformat()
            payload = ({"trial_index": index, "outcome": "completed", "reason": None}
                       if stage == "end" else {"trial_index": index, "stage": stage, "t": None})
            rows.append({"participant": "C01", "seq": seq, "at": at, "actor": "system",
                         "kind": "trial_ended" if stage == "end" else "trial_stage",
                         "payload": json.dumps(payload)})
    return pd.DataFrame(rows, columns=["participant", "seq", "at", "actor", "kind", "payload"])


def test_each_stage_s_time_runs_to_the_trial_s_next_event_in_the_cycle_s_order():
    table = cycle_table(events(
        [("prepare", 0.0), ("loaded", 2.0), ("gaze", 3.0), ("ready", 5.5), ("go", 6.0), ("end", 9.0)],
        [("prepare", 0.0), ("loaded", 4.0), ("ready", 5.0)],  # never ended: ready has no time
    )).set_index("stage")
    assert list(table.index) == [*PAPER_CYCLE.names, "gaze"]  # no longer a stage: still counted
    assert table.loc["prepare", "median_s"] == pytest.approx(3.0)  # 2 s and 4 s
    assert table.loc["prepare", "longest_s"] == pytest.approx(4.0)
    assert table.loc["gaze", "median_s"] == pytest.approx(2.5) and table.loc["gaze", "trials"] == 1
    assert table.loc["ready", "trials"] == 2 and table.loc["ready", "median_s"] == pytest.approx(0.5)
    assert table.loc["go", "median_s"] == pytest.approx(3.0)
    assert table.loc["reach", "trials"] == 0 and pd.isna(table.loc["reach", "median_s"])


def test_a_study_no_trial_of_which_began_has_every_stage_and_no_times():
    table = cycle_table(events()).set_index("stage")
    assert list(table.index) == list(PAPER_CYCLE.names)
    assert (table["trials"] == 0).all() and table["median_s"].isna().all()


def test_a_stored_stage_the_cycle_no_longer_has_is_still_read():
    config = short_config()
    stored = [ev.to_row(event) for event in (
        ev.SessionCreated(seq=1, actor=Actor.EXPERIMENTER, code="C01",
                          config=config.model_dump(mode="json")),
        ev.ThetaPlanned(seq=2, actor=Actor.LEARNER, interaction=1, a=5.0, delta=0.0, k=5.0,
                        origin="sobol"),
        ev.TrialStarted(seq=3, actor=Actor.EXPERIMENTER, trial_index=1, interaction=1, attempt=1),
        ev.TrialStage(seq=4, actor=Actor.SYSTEM, trial_index=1, stage="gaze", t=None))]
    assert replay(protocol_slots(config), stored).stage == "gaze"
