"""The study's LSL outlets (issue 24, item 3), recorded to XDF while a session runs on the wall clock
and read back with pyxdf: the markers and the robot samples agree with the participant's SQLite rows
on order, count and time (within one control period).

Two recorders take the same streams (support/recorded_session.py): the suite's own, which the
session waits on before it stops it, and a real LabRecorder, whose file must hold the same stream
descriptions and a prefix of the same markers (it drops what arrived in its last 500 ms)."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pylsl
import pytest
import pyxdf
from support.recorded_session import XDIST_GROUP, stored_samples

from app.protocol import events as ev
from app.protocol.markers import MARKED, decode, marker
from app.protocol.vocabulary import Actor
from app.session.lsl_outlets import ROBOT_COLUMNS, ROBOT_LABELS
from session_store.store import ParticipantStore

pytestmark = pytest.mark.xdist_group(XDIST_GROUP)


def stream(streams: list[dict], name: str) -> dict:
    return next(s for s in streams if s["info"]["name"][0] == name)


def participant_of(recorded: dict) -> str:
    return recorded["info"]["desc"][0]["participant"][0]


def test_markers_and_robot_samples_recorded_to_xdf_agree_with_the_store(recorded_session):
    session, period = recorded_session, 1 / recorded_session.rate_hz
    store = ParticipantStore.open(session.study, session.code)
    try:
        events = [e for e in store.events() if e.kind in MARKED]
        trials = store.rows("trials", order_by="trial_index")
    finally:
        store.close()
    rows = stored_samples(session.study, session.code)
    # the offset between the stored rows' clock (UTC) and the LSL clock, taken by the test itself
    offset = datetime.now(UTC).timestamp() - pylsl.local_clock()
    streams, _ = pyxdf.load_xdf(session.xdf, dejitter_timestamps=False)
    markers, robot = stream(streams, session.markers), stream(streams, session.robot)
    assert participant_of(markers) == participant_of(robot) == session.code
    assert session.code in markers["info"]["source_id"][0]
    assert session.code in robot["info"]["source_id"][0]

    # the markers: one per marked event, in the order of the events table, at its stored time
    recorded = [decode(m[0]) for m in markers["time_series"]]
    assert [m["seq"] for m in recorded] == [e.seq for e in events]
    assert [m["event"] for m in recorded] == [MARKED[e.kind] or e.payload["stage"] for e in events]
    stored_at = np.array([datetime.fromisoformat(e.at).timestamp() - offset for e in events])
    error = np.abs(markers["time_stamps"] - stored_at)
    assert error.max() < period, f"markers off their stored time by up to {error.max():.6f} s"
    kinds = {m["event"] for m in recorded}
    assert {"trial_start", "go", "release", "trial_end", "placement_confirmed", "answer"} <= kinds
    starts = [m for m in recorded if m["event"] == "trial_start"]
    assert [(m["trial"], m["origin"], m["theta"]["k"]) for m in starts] == \
        [(t.trial_index, t.origin, t.theta_k) for t in trials]

    # the robot stream: every stored sample row of every trial, at Go's marker time + t
    assert float(robot["info"]["nominal_srate"][0]) == session.rate_hz
    labels = [c["label"][0] for c in robot["info"]["desc"][0]["channels"][0]["channel"]]
    assert labels == list(ROBOT_LABELS)
    go = {m["trial"]: ts for m, ts in zip(recorded, markers["time_stamps"], strict=True)
          if m["event"] == "go"}
    series, stamps = robot["time_series"], robot["time_stamps"]
    assert sorted(set(series[:, 0].astype(int))) == sorted(go) == sorted(rows)
    worst = 0.0
    for trial, mine in rows.items():
        recorded_rows = series[:, 0] == trial
        assert recorded_rows.sum() == len(mine["t"]), trial
        worst = max(worst, np.abs(stamps[recorded_rows] - (go[trial] + mine["t"])).max())
        expected = np.column_stack([mine[column].reshape(len(mine["t"]), -1)
                                    for column, _, _ in ROBOT_COLUMNS])
        np.testing.assert_array_equal(series[recorded_rows, 1:], expected)
    assert worst < period, f"robot samples off Go + t by up to {worst:.6f} s"


def test_labrecorder_records_the_same_streams_and_markers(recorded_session):
    """A real LabRecorder: the streams' descriptions, and the markers it pulled before it was
    stopped, in the same order at the same times."""
    session = recorded_session
    ours, _ = pyxdf.load_xdf(session.xdf)
    theirs, _ = pyxdf.load_xdf(session.labrecorder)
    for name in (session.markers, session.robot):
        assert participant_of(stream(theirs, name)) == session.code
        assert stream(theirs, name)["info"]["source_id"] == stream(ours, name)["info"]["source_id"]
    mine, its = stream(ours, session.markers), stream(theirs, session.markers)
    count = len(its["time_series"])
    assert count > 0 and its["time_series"] == mine["time_series"][:count]
    np.testing.assert_allclose(its["time_stamps"], mine["time_stamps"][:count], atol=1e-3)


def test_a_validation_rating_is_marked_with_its_interaction_and_who_rated():
    rated = ev.ValidationRated(seq=41, actor=Actor.PARTICIPANT, interaction=30, rating="better")
    assert marker(rated, state=None) == {"event": "rating", "seq": 41, "interaction": 30,
                                         "rating": "better", "by": "participant"}
