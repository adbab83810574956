"""Every trial's safety record (issue 47): the figures against their definitions on trials whose
answer is known by construction, the record stored with the trial and its end's event and marker,
and ``handover doctor`` taking it again from the samples."""

from __future__ import annotations

import sqlite3
from contextlib import closing

import numpy as np
import pytest
from support.engine import SHORT_PROTOCOL, drive_until, new_engine
from support.runner import Probe

from app.cli import main
from app.protocol.events import parse
from app.protocol.markers import marker
from app.protocol.safety_record import SafetyRecordSettings, over_limits, safety_record
from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.runner import SessionRunner
from app.ui.status_text import safety_markdown
from robot_io.control.recorder import COLUMNS
from robot_io.hands.simulated_hand import Scenario

DT = 0.002  # a 500 Hz loop
TRACKER_DT = 0.01  # a 100 Hz tracker: the loop repeats each hand sample five times


def rows_of(t: np.ndarray, tool: np.ndarray, hand: np.ndarray, stage: np.ndarray,
            pull: np.ndarray) -> dict[str, np.ndarray]:
    """A trial's sample columns: the hand as the loop holds it, at the tracker's samples."""
    n = len(t)
    rows = {name: np.full((n, width), np.nan) if width > 1 else np.full(n, np.nan)
            for name, width, _ in COLUMNS}
    held = np.floor(t / TRACKER_DT + 1e-9) * TRACKER_DT
    rows.update(t=t, measured=tool, stage=stage, pull=pull, hand_t=held,
                hand=np.stack([np.interp(held, t, hand[:, axis]) for axis in range(3)], axis=1))
    return rows


def straight_reach(speed: float = 0.5, stop_at: float = 0.05) -> dict[str, np.ndarray]:
    """The tool moves along x at ``speed`` towards a still hand 0.5 m away and stops ``stop_at``
    from it (the hold); the pull then ramps at 10 N/s from the hold's start, and the gripper opens
    when it reaches 10 N."""
    t = np.arange(0, 3.0, DT)
    arrive = (0.5 - stop_at) / speed
    x = np.minimum(t, arrive) * speed
    tool = np.stack([x, np.zeros_like(t), np.zeros_like(t)], axis=1)
    hand = np.tile([0.5, 0.0, 0.0], (len(t), 1))
    pull = np.where(t >= arrive, (t - arrive) * 10.0, np.nan)
    opened = arrive + 1.0
    stage = np.where(t < arrive, 1.0, np.where(t < opened, 2.0, 3.0))
    pull[t >= opened] = 10.0  # the rows keep the pull's last value after the release
    return rows_of(t, tool, hand, stage, pull)


def test_the_figures_of_a_straight_reach_are_its_distance_speed_and_pull_times():
    record = safety_record(straight_reach(speed=0.5, stop_at=0.05), SafetyRecordSettings())
    assert record.min_distance_m == pytest.approx(0.05, abs=1e-9)
    # within 0.2 m the tool still moves at 0.5 m/s for 0.3 s, straight at the hand
    assert record.speed_near_mps == pytest.approx(0.5, rel=1e-6)
    assert record.closing_speed_mps == pytest.approx(0.5, rel=1e-6)
    # the pull passes 2 N 0.2 s into the hold and opens the gripper at 10 N, 1 s into it
    assert record.pull_to_open_s == pytest.approx(0.8, abs=DT)
    assert record.longest_contact_s == pytest.approx(0.8, abs=2 * DT)
    assert (record.near_radius_m, record.contact_pull_n) == (0.2, 2.0)


def test_the_near_radius_decides_when_speeds_are_taken():
    """A tool that stops 0.3 m from the hand never comes within 0.2 m: no speed near the hand; a
    lab radius of 0.4 m takes them."""
    rows = straight_reach(speed=0.5, stop_at=0.3)
    assert safety_record(rows, SafetyRecordSettings()).speed_near_mps is None
    wide = safety_record(rows, SafetyRecordSettings(near_radius_m=0.4))
    assert wide.speed_near_mps == pytest.approx(0.5, rel=1e-6)


def test_the_closing_speed_follows_the_hand_between_the_trackers_samples():
    """A hand moving at 1 m/s towards a still tool, seen at 100 Hz by a 500 Hz loop: the closing
    speed is 1 m/s, not the 5 m/s of a tracker step read over one cycle."""
    t = np.arange(0, 1.0, DT)
    hand = np.stack([0.6 - t, np.zeros_like(t), np.zeros_like(t)], axis=1)
    tool = np.zeros((len(t), 3))
    rows = rows_of(t, tool, hand, np.ones_like(t), np.full_like(t, np.nan))
    record = safety_record(rows, SafetyRecordSettings())
    assert record.closing_speed_mps == pytest.approx(1.0, rel=0.02)
    assert record.speed_near_mps == 0.0  # the tool never moved
    assert record.pull_to_open_s is None and record.longest_contact_s == 0.0  # no hold, no release


def test_a_trial_is_over_only_the_limits_a_lab_set():
    figures = {**safety_record(straight_reach(), SafetyRecordSettings()).model_dump(),
               "peak_pull_n": 10.0}
    # no limits, no flag; but a contact held past contact_hold_s (0.5 s) is always named
    assert over_limits(figures, SafetyRecordSettings(contact_hold_s=1.0)) == []
    assert over_limits(figures, SafetyRecordSettings()) == \
        ["a contact held 0.80 s (> contact_hold_s 0.5)"]
    lab = SafetyRecordSettings(min_distance_m=0.1, max_speed_near_mps=0.6, max_pull_n=8.0,
                               max_contact_s=2.0)
    assert over_limits(figures, lab) == ["min_distance_m 0.05 < 0.1 (min_distance_m)",
                                         "peak_pull_n 10 > 8 (max_pull_n)"]


def test_the_record_is_stored_with_the_trial_in_its_event_and_marker_and_doctor_checks_it(
        tmp_path, capsys):
    engine = new_engine(tmp_path, "S01")
    drive_until(engine, Step.PLACE)
    (trial,) = engine.store.rows("trials")
    (ended,) = [e for e in engine.store.events() if e.kind == "trial_ended"]
    assert trial.min_distance_m is not None and trial.min_distance_m < 0.2
    assert ended.payload["safety"]["min_distance_m"] == trial.min_distance_m
    sent = marker(parse(ended), engine.state)
    assert sent is not None and sent["safety"]["speed_near_mps"] == trial.speed_near_mps
    path = engine.store.path
    engine.close()
    assert main(["doctor", str(tmp_path)]) == 0
    with closing(sqlite3.connect(path)) as conn, conn:  # the samples changed after the record
        conn.execute("UPDATE samples SET measured_x = measured_x + 0.1")
    assert main(["doctor", str(tmp_path)]) != 0
    assert "trial 1's safety record differs from its samples in min_distance_m" in \
        capsys.readouterr().out


def test_a_trial_over_a_lab_limit_is_flagged_on_the_dashboard_when_it_is_stored(tmp_path):
    """A lab whose limit every handover passes (the tool within 1 m of the hand): the view that
    publishes the trial's end carries the flag, and the dashboard's safety panel shows it."""
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL,
                                    "safety_record": {"min_distance_m": 1.0}})
    runner = SessionRunner(tmp_path / "study", lab, realtime=False)
    probe = Probe(runner)
    runner.set_auto(True)
    try:
        runner.open("F01", Scenario.STRAIGHTFORWARD, seed=3)
        assert runner.view.safety_flags == []
        probe.wait(lambda v: v.step is Step.READY, what="ready for the first trial")
        runner.start_trial()
        view = probe.wait(lambda v: any(t.outcome is not None for t in v.trials), what="trial 1 ended")
        (trial,) = view.trials
        assert view.safety_flags == [f"trial 1: min_distance_m {trial.min_distance_m:.3g} < 1 "
                                     "(min_distance_m)"]
        assert "over the lab's safety limit**: trial 1: min_distance_m" in safety_markdown(view)
    finally:
        runner.close()
