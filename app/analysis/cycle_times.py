"""The handover cycle as a study went through it: for each stage of the cycle (the table of
:mod:`robot_io.control.stages`, in its order), how many trials reached it and how long they stayed in
it, from its ``trial_stage`` event to the trial's next event (its next stage or its end). Before Go
that is how long the move to R, the loading, the wait for the hand and each confirmation of the
experimenter took; a stage no trial reached has no times.
"""

from __future__ import annotations

import json

import pandas as pd

from robot_io.control.stages import current

#: The kinds of stored event that begin or end a stretch of a trial's cycle.
CYCLE_EVENTS = ("trial_stage", "trial_ended")
COLUMNS = ["stage", "trials", "median_s", "longest_s"]


def stage_spans(events: pd.DataFrame) -> pd.DataFrame:
    """One row per stage a trial began: participant, trial_index, stage and ``seconds`` until the
    trial's next stage or its end (missing for the last one of a trial that never ended)."""
    rows = events[events["kind"].isin(CYCLE_EVENTS)].sort_values(["participant", "seq"])
    payloads = rows["payload"].map(json.loads)
    spans = pd.DataFrame({"participant": rows["participant"].to_numpy(),
                          "trial_index": payloads.map(lambda p: p["trial_index"]).to_numpy(),
                          "stage": payloads.map(lambda p: p.get("stage")).to_numpy(),
                          "at": rows["at"].to_numpy()})
    spans["at"] = pd.to_datetime(spans["at"], utc=True, format="ISO8601")  # datetimes, even if none
    following = spans.groupby(["participant", "trial_index"])["at"].shift(-1)
    spans["seconds"] = (following - spans["at"]).dt.total_seconds()
    return spans[spans["stage"].notna()].drop(columns="at")


def cycle_table(events: pd.DataFrame) -> pd.DataFrame:
    """Per stage of the cycle, in its order (then any stage the records name that the cycle no
    longer has): the trials that reached it, the median and the longest time spent in it [s]."""
    spans = stage_spans(events)
    known = list(current().names)
    order = known + sorted(set(spans["stage"]) - set(known))
    rows = []
    for stage in order:
        mine = spans[spans["stage"] == stage]
        seconds = mine["seconds"].dropna()
        rows.append({"stage": stage,
                     "trials": len(mine.drop_duplicates(["participant", "trial_index"])),
                     "median_s": seconds.median() if len(seconds) else None,
                     "longest_s": seconds.max() if len(seconds) else None})
    return pd.DataFrame(rows, columns=COLUMNS)
