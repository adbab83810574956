"""``handover report --xdf`` (issue 24, item 4) on a recorded session (support/recorded_session.py):
a stand-in eye tracker's pupil diameter, recorded beside the study's streams, dilates from ONSET_S
after the robot starts (Go); aligned to the trials by the markers, every trial shows it there."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import pyxdf
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.pupil import BASELINE_MM, ONSET_S, RATE_HZ
from support.recorded_session import XDIST_GROUP
from support.xdf_chunks import FOOTER, HEAD, OFFSET, SAMPLES, chunks

from app.analysis.xdf import XDFError, load_recording
from app.cli import main
from app.protocol.markers import MARKER_TYPE
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.xdist_group(XDIST_GROUP), pytest.mark.slow, pytest.mark.soak]


def test_report_xdf_aligns_the_pupil_stream_to_each_go(recorded_session, tmp_path, capsys):
    """Where its group's worker draws this test first, its time includes ``recorded_session``: a
    short session on the wall clock recorded to XDF by the suite's recorder and a real LabRecorder
    (15-26 s)."""
    session, out = recorded_session, tmp_path / "report"
    assert main(["report", str(session.study), "--out", str(out), "--xdf", str(session.xdf),
                 "--xdf-stream", session.pupil]) == 0, capsys.readouterr().err
    figure = out / "figures" / f"xdf-{session.pupil}-{session.code}.png"
    assert figure.stat().st_size > 0
    assert "Other streams of the XDF recording" in (out / "report.html").read_text()
    aligned = pd.read_csv(out / "tables" / "xdf_around_go.csv")
    assert set(aligned["stream"]) == {session.pupil}
    assert set(aligned["channel"]) == {"pupil_diameter_mm"}
    store = ParticipantStore.open(session.study, session.code)
    try:
        went = [t.trial_index for t in store.rows("trials") if t.go_at is not None]
    finally:
        store.close()
    trials = aligned.groupby("trial_index")
    assert sorted(trials.groups) == went  # every trial that reached Go
    for index, trial in trials:
        t, value = trial["t"].to_numpy(), trial["value"].to_numpy()
        assert t.min() < -0.9 and t.max() > 2.9, index  # the whole window was recorded
        before = value[t < ONSET_S - 1 / RATE_HZ]  # Go, and the pupil's latency after it
        assert np.abs(before - BASELINE_MM).max() < 1e-4, (index, before.max())
        # dilated by 0.15 mm 0.1 s after the onset: a misalignment of more than ~0.1 s shows here
        assert value[(t > ONSET_S + 0.1) & (t < ONSET_S + 0.15)].min() > BASELINE_MM + 0.1, index
        assert value[(t > 0.6) & (t < 0.9)].mean() > BASELINE_MM + 0.4, index  # its peak


def test_report_xdf_names_a_stream_the_file_does_not_hold(recorded_session, tmp_path, capsys):
    session = recorded_session
    assert main(["report", str(session.study), "--out", str(tmp_path / "r"), "--xdf",
                 str(session.xdf), "--xdf-stream", "Pupil"]) == 2
    error = capsys.readouterr().err
    assert "no stream named ['Pupil']" in error and session.pupil in error
    assert not (tmp_path / "r").exists()  # refused before anything was written
    assert main(["report", str(session.study), "--out", str(tmp_path / "r"), "--xdf",
                 str(session.xdf), "--xdf-stream", session.robot]) == 2
    assert "is the study's robot stream" in capsys.readouterr().err


def test_report_xdf_refuses_a_file_without_the_study_markers(recorded_session, tmp_path, capsys):
    session, other = recorded_session, tmp_path / "other.xdf"
    other.write_bytes(b"XDF:")  # an XDF file with nothing recorded in it
    assert main(["report", str(session.study), "--out", str(tmp_path / "r"), "--xdf",
                 str(other)]) == 2
    assert "0 study marker streams" in capsys.readouterr().err
    other.write_text("not an XDF file")
    assert main(["report", str(session.study), "--out", str(tmp_path / "r"), "--xdf",
                 str(other)]) == 2
    assert "not a readable XDF file" in capsys.readouterr().err


#: Where a copy that stopped early ends: so many bytes, half the file, or inside the text of the
#: file's last marker, the last sample of its chunk, which pyxdf reads torn (a run of two suites side
#: by side found half a file cut in such a marker: "error: Unterminated string", the report refused).
MARKER = b'{"event":'


def cut_at(data: bytes, keep: int | float | str) -> int:
    """How many bytes of ``data`` the copy that stopped early at ``keep`` holds."""
    if keep == "inside a marker":
        return data.rindex(MARKER) + len(MARKER) + 5
    return keep if isinstance(keep, int) else int(float(keep) * len(data))


@pytest.mark.parametrize("keep", [100, 1000, 5000, 0.5, "inside a marker"])
def test_report_xdf_on_a_recording_cut_short_says_so_in_a_sentence(recorded_session, tmp_path,
                                                                     capsys, keep):
    """A copy that stopped early: 100–1000 bytes were an XML ParseError traceback, 5000 bytes
    "cannot reshape array of size 0", half a file a report with no warning, and a cut inside a
    marker's text a refusal."""
    session, cut = recorded_session, tmp_path / "cut.xdf"
    data = session.xdf.read_bytes()
    cut.write_bytes(data[:cut_at(data, keep)])
    code = main(["report", str(session.study), "--out", str(tmp_path / "r"), "--xdf", str(cut)])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "reshape" not in err, err
    refused = code == 2 and err.startswith(f"handover report: error: {cut}:")
    reported_cut = code == 0 and f"warning: {cut}: stream" in err and "ends early" in err
    if keep == "inside a marker":  # the markers before it are reported; the torn one is said
        assert reported_cut and "its last marker was cut in the middle and is left out" in err, err
    elif keep == 0.5:  # the first half of every stream is there: reported, and said to end early
        assert reported_cut, err
        page = (tmp_path / "r" / "report.html").read_text()
        assert "Data problems" in page and "XDF recording: stream" in page and "ends early" in page
    elif keep == 5000:  # the streams' headers and maybe their first samples: either, in words
        assert refused or reported_cut, err
    else:
        assert refused, err


def test_report_xdf_refuses_a_marker_stream_naming_no_participant(recorded_session, tmp_path, capsys):
    """The marker stream's description says whose markers they are; one that does not (another
    tool's outlet, an edited header) is refused in words, never reported as "trials of None"."""
    session, renamed = recorded_session, tmp_path / "renamed.xdf"
    data = session.xdf.read_bytes()
    assert b"<participant>" in data  # the marker stream's (and the robot stream's) description
    # the same number of bytes: every chunk keeps its length, only the key is unknown
    renamed.write_bytes(data.replace(b"<participant>", b"<participxnt>").replace(
        b"</participant>", b"</participxnt>"))
    assert main(["report", str(session.study), "--out", str(tmp_path / "r"), "--xdf",
                 str(renamed)]) == 2
    err = capsys.readouterr().err
    assert "the study marker stream's description names no participant" in err, err


@dataclass(frozen=True)
class WholeFile:
    """The recorded session's XDF file as the cut tests read it, once per module: its bytes, its
    study markers, and where its first chunk of markers ends (pyxdf's account of its chunks)."""

    data: bytes
    markers: list[dict]
    chunks: list[tuple[int, int, int | None]]
    first_markers_end: int


@pytest.fixture(scope="module")
def whole_file(recorded_session) -> WholeFile:
    path = recorded_session.xdf
    data = path.read_bytes()
    (ours,) = [h["stream_id"] for h in pyxdf.resolve_streams(str(path)) if h["type"] == MARKER_TYPE]
    found = chunks(data)
    first = next(n for n, (_, tag, stream) in enumerate(found) if tag == SAMPLES and stream == ours)
    return WholeFile(data, [marker for _, marker in load_recording(path).markers], found,
                     found[first + 1][0])


def reported_up_to_the_cut(path: Path, whole: list[dict]) -> list[dict]:
    """The markers of the file cut short at ``path``: those of the whole file up to the cut, and
    the report says the file was cut."""
    recording = load_recording(path)
    markers = [marker for _, marker in recording.markers]
    assert markers and markers == whole[:len(markers)], (path.stat().st_size, markers[-1:])
    assert recording.cut_short, path.stat().st_size
    return markers


@pytest.mark.parametrize("tag", [SAMPLES, OFFSET, FOOTER])
def test_a_cut_in_any_byte_of_a_chunks_head_keeps_what_came_before(whole_file, tmp_path, tag):
    """CI cut half a file inside a chunk's stream id: pyxdf raised "unpack requires a buffer of 4
    bytes" and the report refused a file holding half the recording (a cut in a 1-byte length was
    a TypeError traceback). Cut at every byte of the head and first content of one chunk of each
    kind in the file's second half, it is read up to that chunk and said to be cut."""
    data = whole_file.data
    start = next(s for s, t, _ in whole_file.chunks if t == tag and s > len(data) // 2)
    cut = tmp_path / "cut.xdf"
    counts = set()
    for end in range(start, start + HEAD + 16):
        cut.write_bytes(data[:end])
        counts.add(len(reported_up_to_the_cut(cut, whole_file.markers)))
    assert len(counts) == 1, counts  # a marker is neither lost nor found inside another chunk's head


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(share=st.floats(min_value=0, max_value=1))
def test_a_file_cut_anywhere_is_reported_up_to_the_cut_or_refused_in_words(whole_file, tmp_path,
                                                                          share):
    """Cut at any byte: before the end of the first chunk of markers, a refusal that names the file
    and says why (never "not a readable XDF file": what it holds is readable); after it, the
    markers up to the cut, and the cut said."""
    data = whole_file.data
    cut, end = tmp_path / "cut.xdf", 4 + round(share * (len(data) - 5))
    cut.write_bytes(data[:end])
    if end >= whole_file.first_markers_end:
        reported_up_to_the_cut(cut, whole_file.markers)
        return
    with pytest.raises(XDFError) as refused:
        load_recording(cut)
    assert str(refused.value).startswith(f"{cut}: ") and "not a readable" not in str(refused.value)
