"""The session's own XDF recording (issue 47) against LabRecorder's real engine (the ``labrecorder``
package) and, for LabRecorder's remote control, the stand-in written from its documented commands
(robot_io/standins/labrecorder_rcs.py): what the file holds, a run per open, a killed recorder's
file, a file that stops growing, and every way the remote control can fail."""

from __future__ import annotations

import html
import json
import os
import signal
import socket
import time
import uuid
from pathlib import Path

import pylsl
import pytest
import pyxdf
from pydantic import ValidationError
from support.engine import SHORT_PROTOCOL
from support.recorded_session import PROTOCOL as TWO_HANDOVERS
from support.runner import Probe
from support.waiting import wait_for
from support.xdf_chunks import chunks

from app.analysis.report import build_report
from app.analysis.xdf import load_recording
from app.protocol import events as ev
from app.protocol.errors import RefusedAction
from app.protocol.state import Step
from app.session.config import LabConfig, RecordingSettings
from app.session.rcs_client import RecorderError
from app.session.recording import SessionRecording
from app.session.runner import SessionRunner
from robot_io.control.stages import Stage
from robot_io.hands.simulated_hand import Scenario
from robot_io.standins.labrecorder_rcs import RemoteControl, StandInLabRecorder
from session_store.read_only_copy import reading
from session_store.recordings import recordings_of

pytestmark = [pytest.mark.slow]


def unique(prefix: str) -> str:
    return f"{prefix}-{uuid.uuid4().hex[:10]}"


class LabStream:
    """A stream of the lab's (a stand-in mocap at 50 Hz, pushed on demand)."""

    def __init__(self, name: str, kind: str = "Mocap") -> None:
        self.source_id = unique("src")
        self.outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, kind, 3, 50, pylsl.cf_double64,
                                                          self.source_id))

    def push(self, count: int) -> None:
        """``count`` samples, once the recorder's inlet has subscribed (an outlet sends a consumer
        only what is pushed after it connects)."""
        wait_for(self.outlet.have_consumers, "the recorder's inlet on the lab's stream")
        self.outlet.push_chunk([[0.1, 0.2, 0.3]] * count)


def streams_in(path: Path) -> dict[str, dict]:
    streams, _ = pyxdf.load_xdf(str(path), dejitter_timestamps=False)
    return {s["info"]["name"][0]: s for s in streams}


def run_short_session(runner: SessionRunner, probe: Probe) -> None:
    for _ in range(runner.view.interactions + 4):
        view = probe.wait(lambda v: v.step in (Step.READY, Step.DONE), what="ready, or done")
        if view.step is Step.DONE:
            return
        runner.start_trial()
    raise AssertionError(f"the session did not end: {runner.view.trials}")


def test_a_session_records_its_streams_and_the_labs_and_a_resume_records_a_new_run(tmp_path):
    """A session of two handovers on the mock arm on the wall clock, recorded by LabRecorder's
    engine: the file holds the session's two streams and the lab's named one (a named but absent
    one is a warning before Start), a ``go`` marker for every trial, and its footers; opening the
    participant again records run 2. About 60 s (90 s with another run beside it): two trials on
    the wall clock, and the engine closes each file only after its clock-offset threads end (up to
    5 s)."""
    name, mocap, absent = unique("rec"), unique("Mocap"), unique("Absent")
    lab_stream = LabStream(mocap)
    lab = LabConfig.model_validate({"protocol": TWO_HANDOVERS, "record": {"lsl_name": name},
                                    "recording": {"kind": "labrecorder", "streams": [mocap, absent],
                                                  "resolve_s": 1.0}})
    study = tmp_path / "study"
    runner = SessionRunner(study, lab)
    probe = Probe(runner)
    runner.set_auto(True)
    try:
        runner.open("R01", Scenario.STRAIGHTFORWARD, seed=5)
        recording = runner.view.recording
        assert recording is not None and recording.run == 1
        assert recording.missing == [absent]  # shown before the first Start
        assert set(recording.streams) == {f"{name}-markers", f"{name}-robot", mocap}
        lab_stream.push(50)  # before the session's last marker, after which the recording stops
        run_short_session(runner, probe)
        runner.end_session()
        runner.open("R01")
        assert runner.view.recording is not None and runner.view.recording.run == 2
    finally:
        runner.close()
    first, second = recordings_of(study, "R01")
    assert first.name == "sub-R01_ses-01_task-handover_run-001_beh.xdf"
    assert second.name.endswith("_run-002_beh.xdf")
    streams = streams_in(first)
    assert set(streams) == {f"{name}-markers", f"{name}-robot", mocap}
    assert all(s["footer"] for s in streams.values())  # stopped cleanly: every footer written
    assert len(streams[mocap]["time_stamps"]) == 50
    markers = [json.loads(text[0]) for text in streams[f"{name}-markers"]["time_series"]]
    with reading(study, "R01") as store:
        trials = [t.trial_index for t in store.rows("trials")]
    gos = sorted(m["trial"] for m in markers if m["event"] == "go")
    assert gos == trials and markers[-1]["event"] == "answer"  # the last marker is in the file
    ended = [m for m in markers if m["event"] == "trial_end"]
    assert all(m["safety"]["min_distance_m"] is not None for m in ended)
    # the report finds the runs itself and matches every stored Go; without run 1 it names them
    report = build_report(study, tmp_path / "report")
    assert report.gos_not_recorded == {}
    assert "R01: every stored trial's Go marker is in the recording" in \
        html.unescape(report.html.read_text())
    # a recording cut inside its last marker's text (a recorder killed there; pyxdf reads the torn
    # text, the last of its chunk): the markers before it are counted, the torn one is said
    whole = first.read_bytes()
    first.write_bytes(whole[:whole.rindex(b'{"event":') + 12])
    report = build_report(study, tmp_path / "report")
    assert report.gos_not_recorded == {}
    page = html.unescape(report.html.read_text())
    assert "its last marker was cut in the middle and is left out" in page
    assert "unreadable" not in page  # the file is read, up to the torn marker
    # cut in the head of its last chunk (a footer), between its length and its tag: read up to it
    first.write_bytes(whole[:chunks(whole)[-1][0] + 2])
    report = build_report(study, tmp_path / "report")
    assert report.gos_not_recorded == {}
    assert "bytes into a chunk, which is left out" in html.unescape(report.html.read_text())
    first.write_bytes(whole)
    first.rename(first.with_suffix(".moved"))
    report = build_report(study, tmp_path / "report")
    assert report.gos_not_recorded == {"R01": ", ".join(map(str, trials))}


def _engine_recording(tmp_path: Path, stream: LabStream, **settings) -> tuple[SessionRecording, list]:
    notes: list[str] = []
    recording = SessionRecording(RecordingSettings(kind="labrecorder", **settings), tmp_path, "K01",
                                 [stream.source_id], notes.append)
    return recording, notes


def test_a_killed_recorder_leaves_a_file_pyxdf_reads_without_its_footer(tmp_path):
    """The engine process killed mid-recording (SIGKILL: no footer, nor what its file buffer held:
    the engine writes through a C++ file stream, whose buffer takes writes below 1 kB, so a slow
    stream reaches the disk in 8 kB steps): pyxdf reads every chunk written before."""
    stream = LabStream(unique("Kill"))
    recording, _ = _engine_recording(tmp_path, stream)
    try:
        for _ in range(6):  # 3 s of data: the engine writes a chunk (3.2 kB here) every 500 ms
            stream.push(100)
            time.sleep(0.5)
        wait_for(lambda: recording.path.stat().st_size > 2000, "the engine's chunks on disk",
                 seen=lambda: recording.path.stat().st_size)
        assert recording._engine is not None
        os.kill(recording._engine.process.pid, signal.SIGKILL)
    finally:
        recording.close()
    (read,) = streams_in(recording.path).values()
    assert "footer" not in read and 0 < len(read["time_stamps"]) <= 600
    headers = pyxdf.resolve_streams(str(recording.path))
    assert [h["name"] for h in headers] == [stream.outlet.get_info().name()]
    with pytest.raises(Exception, match="study marker streams"):  # readable, but not a session's
        load_recording(recording.path)


def test_a_file_that_stops_growing_while_a_trial_streams_is_warned_about(tmp_path):
    stream = LabStream(unique("Stall"))
    recording, notes = _engine_recording(tmp_path, stream, stall_s=1.0)
    try:
        go = ev.TrialStage(actor="system", trial_index=1, stage=Stage.GO, t=0.0)
        recording.on_event(go, None)  # type: ignore[arg-type]  # the listener reads the event only
        wait_for(lambda: recording.status().warning, "the recording's stall warning",
                 seen=recording.status)
        assert "stopped growing" in notes[0]
        for _ in range(4):
            stream.push(50)
            time.sleep(0.5)
        wait_for(lambda: recording.status().warning is None, "the warning cleared as it grows",
                 seen=recording.status)
    finally:
        recording.close()


@pytest.fixture
def stand_in():
    """Start a stand-in LabRecorder that sees only the test's own ``streams`` (the other tests'
    streams come and go on this machine) and records them; every one is closed afterwards."""
    servers = []

    def start(*streams: LabStream, silent: bool = False) -> RemoteControl:
        ours = {stream.source_id for stream in streams}
        servers.append(RemoteControl(StandInLabRecorder(
            silent, sees=lambda info: info.source_id() in ours)))
        return servers[-1]

    yield start
    for server in servers:
        server.close()


def _rcs(port: int, tmp_path: Path, stream: LabStream) -> SessionRecording:
    settings = RecordingSettings(kind="labrecorder_rcs", rcs_port=port)
    return SessionRecording(settings, tmp_path, "C01", [stream.source_id], print)


def test_labrecorder_over_its_remote_control_records_the_study_file(tmp_path, stand_in):
    stream = LabStream(unique("Rcs"))
    server = stand_in(stream)
    recording = _rcs(server.port, tmp_path, stream)
    stream.push(50)
    recording.close()
    lines = server.recorder.lines
    assert lines[:3] == ["stop", "select all", f"filename {{root:{(tmp_path / 'recordings').resolve()}}} "
                         "{template:sub-%p/ses-%s/%m/sub-%p_ses-%s_task-%b_run-%n_%m.xdf} "
                         "{participant:C01} {session:01} {task:handover} {modality:beh} {run:1}"]
    assert lines[3:] == ["start", "stop"]
    assert server.recorder.path == recording.path  # LabRecorder named it as the study does
    assert stream.outlet.get_info().name() in streams_in(recording.path)


def test_a_labrecorder_left_recording_by_a_crashed_session_records_the_next_run(tmp_path, stand_in):
    """A session killed leaves the lab's LabRecorder recording its run (nobody sent stop), and a
    LabRecorder that records ignores start: the next run's start stops it first."""
    stream = LabStream(unique("Crashed"))
    server = stand_in(stream)
    first = _rcs(server.port, tmp_path, stream)
    first._stopping.set()  # the session dies: its recording is never closed
    second = _rcs(server.port, tmp_path, stream)
    second.close()
    assert first.path.name.endswith("_run-001_beh.xdf") and second.path.name.endswith("_run-002_beh.xdf")
    assert server.recorder.path == second.path and first.path.exists()


def test_a_recorder_that_answers_ok_and_writes_nothing_is_caught_at_the_start(tmp_path, stand_in):
    stream = LabStream(unique("Silent"))
    server = stand_in(stream, silent=True)
    began = time.monotonic()
    with pytest.raises(RecorderError, match=r"LabRecorder answered OK, but no file .* appeared "
                                            r"within 4 s: the session is not being recorded"):
        _rcs(server.port, tmp_path, stream)
    print(f"caught after {time.monotonic() - began:.2f} s")
    assert server.recorder.lines[-1] == "stop"  # told to stop what it never started


def test_a_refused_connection_and_a_bad_port_are_named(tmp_path):
    with socket.socket() as free:  # a port nothing listens on
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    with pytest.raises(RecorderError, match=rf"127.0.0.1:{port} refused the connection: is "
                                            "LabRecorder running with 'EnableRCS'"):
        _rcs(port, tmp_path, LabStream(unique("Refused")))
    for bad in (0, 70000, "22345"):
        with pytest.raises(ValidationError, match=r"rcs_port[\s\S]*whole number in \[1, 65535\]"):
            LabConfig.model_validate({"recording": {"kind": "labrecorder_rcs", "rcs_port": bad}})


def test_a_session_whose_recording_does_not_start_does_not_open(tmp_path, stand_in):
    server = stand_in(silent=True)
    lab = LabConfig.model_validate({"protocol": SHORT_PROTOCOL,
                                    "record": {"lsl_name": unique("silent")},
                                    "recording": {"kind": "labrecorder_rcs",
                                                  "rcs_port": server.port}})
    runner = SessionRunner(tmp_path / "study", lab)
    try:
        with pytest.raises(RefusedAction, match="the session's recording did not start"):
            runner.open("N01", Scenario.STRAIGHTFORWARD, seed=2)
        assert runner.view.code is None
        # the participant was let go (its writer lock released): opening it again meets the
        # recorder again, not a lock
        with pytest.raises(RefusedAction, match="the session's recording did not start"):
            runner.open("N01")
    finally:
        runner.close()
