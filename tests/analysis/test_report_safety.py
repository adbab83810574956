"""The report's safety record and recordings check (issue 47) as functions of the tables: the
median and the extreme of each figure with the trial it happened in, per participant and study, each
trial judged by the lab's limits in force when it was stored, and which stored Go markers no
recording holds; and the report of a session run with limits, on the terminal, the page and in CSV."""

from __future__ import annotations

import json
import re

import pandas as pd
import pytest
from support.engine import BRIEF_PROTOCOL, SESSION_LOOP_TOML, protocol_toml

from app.analysis.recordings import go_check
from app.analysis.safety import judged_by_lab_limits, safety_summary
from app.cli import main


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


def event(code: str, seq: int, kind: str, **payload: object) -> dict:
    return {"participant": code, "seq": seq, "at": f"2026-01-01T00:00:{seq:02d}+00:00",
            "actor": "system", "kind": kind, "payload": json.dumps(payload)}


def opened(code: str, seq: int, **limits: float) -> dict:
    """A ``devices_recorded`` event whose lab file's [safety_record] sets ``limits``."""
    return event(code, seq, "devices_recorded", config={"safety_record": limits}, devices={})


def test_each_trial_is_judged_by_the_limits_in_force_when_it_was_stored():
    trials = pd.DataFrame({
        "participant": ["P01", "P01", "P01", "P02", "P02"], "trial_index": [1, 2, 3, 1, 2],
        "min_distance_m": [0.05, 0.04, 0.02, 0.04, None],
        "speed_near_mps": [0.3, 0.6, 0.2, 0.9, None], "closing_speed_mps": [None] * 5,
        "peak_pull_n": [10.0, 12.0, 12.0, 10.5, None], "pull_to_open_s": [0.1, 0.2, 0.3, 0.4, None],
        "longest_contact_s": [0.0, 0.0, 0.0, 0.7, None]})
    events = pd.DataFrame([
        opened("P01", 1, max_pull_n=11.0),
        event("P01", 2, "trial_ended", trial_index=1), event("P01", 3, "trial_ended", trial_index=2),
        opened("P01", 4, min_distance_m=0.03),  # a resume with another lab file: no pull limit
        event("P01", 5, "trial_ended", trial_index=3),
        event("P02", 1, "trial_ended", trial_index=1),  # no devices recorded: the defaults
        event("P02", 2, "trial_ended", trial_index=2)])
    judged = judged_by_lab_limits(trials, events.sample(frac=1, random_state=3))  # any order
    assert judged.to_dict("records") == [
        {"participant": "P01", "trial_index": 1, "limits": "max_pull_n 11", "over": ""},
        {"participant": "P01", "trial_index": 2, "limits": "max_pull_n 11",
         "over": "peak_pull_n 12 > 11 (max_pull_n)"},
        {"participant": "P01", "trial_index": 3, "limits": "min_distance_m 0.03",
         "over": "min_distance_m 0.02 < 0.03 (min_distance_m)"},
        {"participant": "P02", "trial_index": 1, "limits": "",
         "over": "a contact held 0.70 s (> contact_hold_s 0.5)"},
        {"participant": "P02", "trial_index": 2, "limits": "", "over": ""}]


@pytest.mark.slow
def test_a_session_run_with_limits_is_reported_past_them_on_the_terminal_page_and_csv(tmp_path,
                                                                                       capsys):
    """Slow (~20 s in a loaded full run): a whole simulated session through `run-session --auto`
    with a lab file that sets a pull limit every handover passes and a speed limit none reaches,
    then `handover report`."""
    lab, study = tmp_path / "lab.toml", tmp_path / "study"
    lab.write_text(f"{SESSION_LOOP_TOML}[protocol]\n{protocol_toml(BRIEF_PROTOCOL)}\n"
                   "[safety_record]\nmax_pull_n = 1.0\nmax_speed_near_mps = 10.0\n")
    assert main(["run-session", "--study", str(study), "--participant", "S01", "--auto",
                 "--scenario", "straightforward", "--seed", "4", "--config", str(lab),
                 "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["report", str(study), "--out", str(tmp_path / "report")]) == 0
    err = capsys.readouterr().err
    judged = pd.read_csv(tmp_path / "report" / "tables" / "safety_limits.csv", keep_default_na=False)
    assert len(judged) == 3 and set(judged["limits"]) == {"max_speed_near_mps 10, max_pull_n 1"}
    pulls = [float(m) for m in re.findall(r"peak_pull_n ([\d.]+) > 1 \(max_pull_n\)",
                                          " ".join(judged["over"]))]
    assert len(pulls) == 3 and min(pulls) > 1.0, judged["over"].tolist()  # every handover was pulled
    assert "speed" not in " ".join(judged["over"])
    for row in judged.itertuples():
        assert (f"warning: past the lab's safety limits: S01 trial {row.trial_index}: {row.over}"
                in err)
    page = (tmp_path / "report" / "report.html").read_text()
    assert "in force when each trial was stored: S01: max_speed_near_mps 10, max_pull_n 1." in page
    assert "3 of 3 trials went past them:" in page
