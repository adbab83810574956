"""The study's LSL outlets (issue 24, item 3), recorded to XDF while a session runs on the wall clock
and read back with pyxdf: the markers and the robot samples agree with the participant's SQLite rows
on order, count and time (within one control period).

Two recorders take the same streams: the suite's own (support/xdf_recorder.py), which the test can
ask what it has received before it stops it, and a real LabRecorder, whose file must hold the same
stream descriptions and a prefix of the same markers (it drops what arrived in its last 500 ms)."""

from __future__ import annotations

import uuid
from datetime import UTC, datetime

import numpy as np
import pylsl
import pyxdf
from support.lab_recorder import LabRecorder
from support.runner import Probe
from support.waiting import wait_for
from support.xdf_recorder import XDFRecorder

from app.protocol.markers import MARKED, decode, marker
from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.lsl_outlets import ROBOT_COLUMNS, ROBOT_LABELS
from app.session.replay import stored_rows
from app.session.runner import SessionRunner
from robot_io.simulated_hand import Scenario
from session_store.store import ParticipantStore

#: Two placed interactions and the questionnaire: every kind of marker but the validation rating
#: (tested on its own below), in a session of two handovers.
PROTOCOL = {"initial_trials": 2, "batch_size": 2, "learning_batches": 0, "without_learning": True,
            "best_trials": 0, "validation_batches": 0}
RATE_HZ = 125
CODE = "L01"


def run_session(runner: SessionRunner, probe: Probe) -> None:
    """Start each trial when the session is ready for it, until it is done."""
    for _ in range(6):  # two trials, and a few repeats should one not complete
        view = probe.wait(lambda v: v.step in (Step.READY, Step.DONE), what="ready to start, or done")
        if view.step is Step.DONE:
            return
        runner.start_trial()
    raise AssertionError(f"the session did not end: {probe.runner.view.trials}")


def stream(streams: list[dict], name: str) -> dict:
    return next(s for s in streams if s["info"]["name"][0] == name)


def participant_of(recorded: dict) -> str:
    return recorded["info"]["desc"][0]["participant"][0]


def test_markers_and_robot_samples_recorded_to_xdf_agree_with_the_store(tmp_path):
    name = f"test-{uuid.uuid4().hex[:12]}"  # a stream name of this test's own
    lab = LabConfig.model_validate({"loop": {"rate_hz": RATE_HZ}, "protocol": PROTOCOL,
                                    "record": {"lsl_name": name}})
    names = [f"{name}-markers", f"{name}-robot"]
    runner = SessionRunner(tmp_path / "study", lab, realtime_priority=True)
    probe = Probe(runner)
    runner.set_auto(True)
    try:
        runner.open(CODE, Scenario.STRAIGHTFORWARD, seed=4)
        ours = XDFRecorder(tmp_path / "ours.xdf", names)
        theirs = LabRecorder(tmp_path / "labrecorder.xdf", names)
        run_session(runner, probe)
        store = ParticipantStore.open(runner.study, CODE)
        try:
            events = [e for e in store.events() if e.kind in MARKED]
            trials = store.rows("trials", order_by="trial_index")
            rows = {t.trial_index: stored_rows(store.samples(t.trial_index)) for t in trials}
        finally:
            store.close()
        rows = {i: {k: v[np.isfinite(r["t"])] for k, v in r.items()} for i, r in rows.items()}
        count = sum(len(r["t"]) for r in rows.values())
        wait_for(lambda: (decode(ours.received(names[0])[0][-1][0])["seq"] == events[-1].seq
                          and len(ours.received(names[1])[1]) == count),
                 f"the recording to hold marker {events[-1].seq} and {count} robot samples",
                 seen=lambda: (f"{len(ours.received(names[0])[1])} markers, "
                               f"{len(ours.received(names[1])[1])} robot samples"))
        theirs.stop()
        path = ours.close()
    finally:
        runner.close()
    # the offset between the stored rows' clock (UTC) and the LSL clock, taken by the test itself
    offset = datetime.now(UTC).timestamp() - pylsl.local_clock()
    streams, _ = pyxdf.load_xdf(path, dejitter_timestamps=False)
    markers, robot = stream(streams, names[0]), stream(streams, names[1])
    assert participant_of(markers) == participant_of(robot) == CODE
    assert CODE in markers["info"]["source_id"][0] and CODE in robot["info"]["source_id"][0]

    # the markers: one per marked event, in the order of the events table, at its stored time
    recorded = [decode(m[0]) for m in markers["time_series"]]
    assert [m["seq"] for m in recorded] == [e.seq for e in events]
    assert [m["event"] for m in recorded] == [MARKED[e.kind] or e.payload["stage"] for e in events]
    stored_at = np.array([datetime.fromisoformat(e.at).timestamp() - offset for e in events])
    error = np.abs(markers["time_stamps"] - stored_at)
    assert error.max() < 1 / RATE_HZ, f"markers off their stored time by up to {error.max():.6f} s"
    kinds = {m["event"] for m in recorded}
    assert {"trial_start", "go", "release", "trial_end", "placement_confirmed", "answer"} <= kinds
    starts = [m for m in recorded if m["event"] == "trial_start"]
    assert [(m["trial"], m["origin"], m["theta"]["k"]) for m in starts] == \
        [(t.trial_index, t.origin, t.theta_k) for t in trials]

    # the robot stream: every stored sample row of every trial, at Go's marker time + t
    assert float(robot["info"]["nominal_srate"][0]) == RATE_HZ
    labels = [c["label"][0] for c in robot["info"]["desc"][0]["channels"][0]["channel"]]
    assert labels == list(ROBOT_LABELS)
    go = {m["trial"]: ts for m, ts in zip(recorded, markers["time_stamps"], strict=True)
          if m["event"] == "go"}
    series, stamps = robot["time_series"], robot["time_stamps"]
    assert sorted(set(series[:, 0].astype(int))) == sorted(go)
    worst = 0.0
    for trial, mine in rows.items():
        recorded_rows = series[:, 0] == trial
        assert recorded_rows.sum() == len(mine["t"]), trial
        worst = max(worst, np.abs(stamps[recorded_rows] - (go[trial] + mine["t"])).max())
        expected = np.column_stack([mine[column].reshape(len(mine["t"]), -1)
                                    for column, _, _ in ROBOT_COLUMNS])
        np.testing.assert_array_equal(series[recorded_rows, 1:], expected)
    assert worst < 1 / RATE_HZ, f"robot samples off Go + t by up to {worst:.6f} s"

    # LabRecorder recorded the same streams, and the same markers up to where it stopped pulling
    theirs_streams, _ = pyxdf.load_xdf(theirs.finished())
    theirs_markers = stream(theirs_streams, names[0])
    assert participant_of(theirs_markers) == participant_of(stream(theirs_streams, names[1])) == CODE
    prefix = [m[0] for m in theirs_markers["time_series"]]
    assert prefix and prefix == [m[0] for m in markers["time_series"]][:len(prefix)]


def test_a_validation_rating_is_marked_with_its_interaction_and_who_rated():
    from app.protocol import events as ev
    from app.protocol.vocabulary import Actor

    rated = ev.ValidationRated(seq=41, actor=Actor.PARTICIPANT, interaction=30, rating="better")
    assert marker(rated, state=None) == {"event": "rating", "seq": 41, "interaction": 30,
                                         "rating": "better", "by": "participant"}
