"""The report's safety record and recordings check (issue 47) as functions of the tables: the
median and the extreme of each figure with the trial it happened in, per participant and study, and
which stored Go markers no recording holds."""

from __future__ import annotations

import pandas as pd
import pytest

from app.analysis.recordings import go_check
from app.analysis.safety import safety_summary


def test_the_summary_takes_each_figures_median_and_extreme_with_its_trial():
    trials = pd.DataFrame({
        "participant": ["P01", "P01", "P01", "P02", "P02"],
        "trial_index": [1, 2, 3, 1, 2],
        "min_distance_m": [0.05, 0.02, 0.08, 0.04, None],
        "speed_near_mps": [0.3, 0.6, None, 0.9, 0.1],
        "closing_speed_mps": [None] * 5, "peak_pull_n": [10.0, 11.0, 12.0, 10.5, 10.1],
        "pull_to_open_s": [0.1, 0.2, 0.3, 0.4, 0.5], "longest_contact_s": [0.0] * 5})
    summary = safety_summary(trials).set_index(["scope", "figure"])
    assert summary.loc[("P01", "min_distance_m")].to_dict() == {
        "n": 3, "median": 0.05, "extreme": 0.02, "participant": "P01", "trial_index": 2}
    assert summary.loc[("study", "min_distance_m"), "extreme"] == 0.02  # the closest: a minimum
    assert summary.loc[("study", "speed_near_mps")].to_dict() == {
        "n": 4, "median": pytest.approx(0.45), "extreme": 0.9, "participant": "P02",
        "trial_index": 1}
    assert ("study", "closing_speed_mps") not in summary.index  # no trial has it
    assert summary.loc[("P02", "pull_to_open_s"), "trial_index"] == 2


def test_the_go_check_names_the_stored_trials_no_recording_holds():
    check = go_check({"P01": {1, 2, 3, 4}, "P02": {1}}, {"P01": {1, 3}, "P02": {1}})
    assert check.to_dict("records") == [
        {"participant": "P01", "stored_gos": 4, "recorded": 2, "missing": "2, 4"},
        {"participant": "P02", "stored_gos": 1, "recorded": 1, "missing": ""}]
