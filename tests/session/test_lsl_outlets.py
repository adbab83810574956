"""The study's LSL outlets (issue 24, item 3), recorded to XDF while a session runs on the wall clock
and read back with pyxdf: the markers and the robot samples agree with the participant's SQLite rows
on order, count and time (within one control period).

Two recorders take the same streams (support/recorded_session.py): the suite's own, which the
session waits on before it stops it, and a real LabRecorder, whose file must hold the same stream
descriptions and a prefix of the same markers (it drops what arrived in its last 500 ms)."""

from __future__ import annotations

import numpy as np
import pytest
import pyxdf
from support.recorded_session import XDIST_GROUP, agreement, named

from app.protocol.markers import MARKED
from app.session.lsl_outlets import ROBOT_CHANNELS
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.xdist_group(XDIST_GROUP), pytest.mark.slow, pytest.mark.soak]


def participant_of(recorded: dict) -> str:
    return recorded["info"]["desc"][0]["participant"][0]


def test_markers_and_robot_samples_recorded_to_xdf_agree_with_the_store(recorded_session):
    session, period = recorded_session, 1 / recorded_session.rate_hz
    found = agreement(session)
    # the markers: one per marked event, in the order of the events table, at its stored time
    assert [m["seq"] for m in found.recorded] == [e.seq for e in found.stored]
    assert [m["event"] for m in found.recorded] == [MARKED[e.kind] or e.payload["stage"]
                                                    for e in found.stored]
    assert found.marker_error_s < period, \
        f"markers off their stored time by {found.marker_error_s} s; wall clock steps: {found.clock_steps}"
    kinds = {m["event"] for m in found.recorded}
    assert {"trial_start", "go", "release", "trial_end", "placement_confirmed", "answer"} <= kinds
    store = ParticipantStore.open(session.study, session.code)
    try:
        trials = store.rows("trials", order_by="trial_index")
    finally:
        store.close()
    starts = [m for m in found.recorded if m["event"] == "trial_start"]
    assert [(m["trial"], m["origin"], m["theta"]["k"]) for m in starts] == \
        [(t.trial_index, t.origin, t.theta_k) for t in trials]
    # the robot stream: every stored sample row of every trial, its values, at Go's marker + t
    assert sorted(found.robot_counts) == [t.trial_index for t in trials]
    assert all(recorded == stored > 0 for recorded, stored in found.robot_counts.values()), \
        found.robot_counts
    assert found.robot_equal
    assert found.robot_error_s < period, f"robot samples off Go + t by {found.robot_error_s} s"
    assert abs(found.rate_hz - session.rate_hz) < 1.0, found.rate_hz
    # the streams' descriptions: the participant, a source_id of the session, the channels
    streams, _ = pyxdf.load_xdf(session.xdf)
    markers, robot = named(streams, session.markers), named(streams, session.robot)
    assert participant_of(markers) == participant_of(robot) == session.code
    assert session.code in markers["info"]["source_id"][0]
    assert session.code in robot["info"]["source_id"][0]
    assert float(robot["info"]["nominal_srate"][0]) == session.rate_hz
    channels = robot["info"]["desc"][0]["channels"][0]["channel"]
    assert [(c["label"][0], c["unit"][0]) for c in channels] == list(ROBOT_CHANNELS)


def test_labrecorder_records_the_same_streams_and_markers(recorded_session):
    """A real LabRecorder: the streams' descriptions, and the markers it pulled before it was
    stopped, in the same order at the same times."""
    session = recorded_session
    ours, _ = pyxdf.load_xdf(session.xdf)
    theirs, _ = pyxdf.load_xdf(session.labrecorder)
    for name in (session.markers, session.robot):
        assert participant_of(named(theirs, name)) == session.code
        assert named(theirs, name)["info"]["source_id"] == named(ours, name)["info"]["source_id"]
    mine, its = named(ours, session.markers), named(theirs, session.markers)
    count = len(its["time_series"])
    assert count > 0 and its["time_series"] == mine["time_series"][:count]
    np.testing.assert_allclose(its["time_stamps"], mine["time_stamps"][:count], atol=1e-3)
