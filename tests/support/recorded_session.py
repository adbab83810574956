"""A short session on the wall clock whose LSL outlets are recorded to XDF, as a lab records them:
the study's robot and marker streams beside a stand-in eye tracker's pupil diameter
(support/pupil.py), by the suite's own recorder (support/xdf_recorder.py, which the session waits
on before it stops it) and by a real LabRecorder. tests/session/test_lsl_outlets.py checks the
recording against the SQLite rows; tests/analysis/test_xdf_report.py runs ``report --xdf`` on it.
Both use the session-scoped fixture ``recorded_session`` (tests/conftest.py) in one xdist group,
:data:`XDIST_GROUP`, so the session runs once per run.
"""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np
import pyxdf

from app.analysis.xdf import WINDOW_S
from app.protocol.markers import MARKED, decode
from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.lsl_outlets import ROBOT_COLUMNS
from app.session.runner import SessionRunner
from robot_io.hands.simulated_hand import Scenario
from session_store.models import Event
from session_store.sample_rows import stored_rows
from session_store.store import ParticipantStore
from support.clocks import ClockWatch, offsets_around, wall_clock_steps
from support.lab_recorder import LabRecorder
from support.pupil import PupilTracker
from support.runner import Probe
from support.waiting import wait_for
from support.xdf_recorder import XDFRecorder

XDIST_GROUP = "lsl-recorded-session"
#: Two placed interactions and the questionnaire: every kind of marker but the validation rating
#: (tests/session/test_lsl_outlets.py checks that one on its own), in a session of two handovers.
PROTOCOL = {"initial_trials": 2, "batch_size": 2, "learning_batches": 0, "without_learning": True,
            "best_trials": 0, "validation_batches": 0}
RATE_HZ = 125
CODE = "L01"
#: How long after an event its marker can have been pushed [s]: the product maps the stored time
#: onto the LSL clock then, through the wall clock's offset of that moment.
PUSHED_WITHIN_S = 5.0


@dataclass(frozen=True)
class RecordedSession:
    study: Path
    code: str
    rate_hz: int
    markers: str  # the streams' names (unique to this run)
    robot: str
    pupil: str
    xdf: Path  # the suite's recorder's file
    labrecorder: Path  # LabRecorder's file (without its last pull interval)
    offsets: np.ndarray  # UTC − monotonic through the session: (monotonic, offset) rows (ClockWatch)


def run_trials(runner: SessionRunner, probe: Probe, interactions: int) -> None:
    """Start each trial when the session is ready for it, until it is done."""
    for _ in range(interactions + 4):  # a few repeats should a trial not complete
        view = probe.wait(lambda v: v.step in (Step.READY, Step.DONE), what="ready to start, or done")
        if view.step is Step.DONE:
            return
        runner.start_trial()
    raise AssertionError(f"the session did not end: {probe.runner.view.trials}")


def stored_samples(study: Path, code: str) -> dict[int, dict[str, np.ndarray]]:
    """Every trial's stored sample rows (those with a trial time), by trial index."""
    store = ParticipantStore.open(study, code)
    try:
        rows = {t.trial_index: stored_rows(store.samples(t.trial_index)) for t in store.rows("trials")}
    finally:
        store.close()
    return {i: {k: v[np.isfinite(r["t"])] for k, v in r.items()} for i, r in rows.items()}


def last_marked_seq(study: Path, code: str) -> int:
    store = ParticipantStore.open(study, code)
    try:
        return max(e.seq for e in store.events() if e.kind in MARKED)
    finally:
        store.close()


def record_session(folder: Path, protocol: dict = PROTOCOL, pupil_spread: float = 0.0,
                   pupil_noise_mm: float = 0.0, lsl_name: str | None = None) -> RecordedSession:
    """Run the session (``protocol``: the lab's [protocol]) with the recorders on; return once both
    files are written. ``pupil_*``: the stand-in eye tracker's variation (support/pupil.py).
    ``lsl_name``: the streams' names begin with it (by default a name of this run's own)."""
    name = lsl_name or f"test-{uuid.uuid4().hex[:12]}"
    markers, robot, pupil = f"{name}-markers", f"{name}-robot", f"{name}-pupil"
    lab = LabConfig.model_validate({"loop": {"rate_hz": RATE_HZ}, "protocol": protocol,
                                    "record": {"lsl_name": name}})
    runner = SessionRunner(folder / "study", lab, realtime_priority=True)
    probe = Probe(runner)
    runner.set_auto(True)
    tracker = theirs = None
    watch = ClockWatch()
    try:
        runner.open(CODE, Scenario.STRAIGHTFORWARD, seed=4)  # the outlets open with the participant
        tracker = PupilTracker(pupil, robot, pupil_spread, pupil_noise_mm)
        names = [markers, robot, pupil]
        ours = XDFRecorder(folder / "session.xdf", names)
        theirs = LabRecorder(folder / "labrecorder.xdf", names)
        run_trials(runner, probe, runner.view.interactions)
        last, count = last_marked_seq(runner.study, CODE), sum(
            len(r["t"]) for r in stored_samples(runner.study, CODE).values())

        def recorded() -> bool:
            """The recording holds the last marker, every stored robot sample, and the pupil for
            the whole window after the last Go that the report draws."""
            texts, stamps = ours.received(markers)
            go = [stamp for text, stamp in zip(texts, stamps, strict=True)
                  if decode(text[0])["event"] == "go"]
            pupil_stamps = ours.received(pupil)[1]
            return (bool(texts) and decode(texts[-1][0])["seq"] == last
                    and len(ours.received(robot)[1]) == count
                    and bool(pupil_stamps) and pupil_stamps[-1] > go[-1] + WINDOW_S[1])

        wait_for(recorded, f"the recording to hold marker {last}, {count} robot samples and "
                           f"{WINDOW_S[1]} s of pupil after the last Go",
                 seen=lambda: (f"{len(ours.received(markers)[1])} markers, last "
                               f"{ours.received(markers)[0][-1:]}, "
                               f"{len(ours.received(robot)[1])} robot samples, pupil until "
                               f"{ours.received(pupil)[1][-1:]}"))
        theirs.stop()
        xdf = ours.close()
        labrecorder = theirs.finished()
    finally:
        if theirs is not None:
            theirs.kill()  # nothing once it has exited
        if tracker is not None:
            tracker.close()
        runner.close()
        offsets = watch.stop()
    return RecordedSession(folder / "study", CODE, RATE_HZ, markers, robot, pupil, xdf, labrecorder,
                           offsets)


@dataclass(frozen=True)
class Agreement:
    """The recording (the suite's recorder's file, read with pyxdf) against the SQLite rows."""

    stored: list[Event]  # the marked events, in the order of the events table
    recorded: list[dict]  # the markers, in the order of the recording
    marker_error_s: float  # max |marker time − its event's stored time (mapped onto the LSL clock)|
    clock_steps: list[tuple[float, float]]  # (monotonic, step [s]) of the wall clock in the session
    robot_counts: dict[int, tuple[int, int]]  # trial → (samples recorded, sample rows stored)
    robot_error_s: float  # max |robot sample time − (its trial's go marker + its stored t)|
    robot_equal: bool  # every recorded robot sample holds its stored row's values
    rate_hz: float  # the robot stream's median rate within a trial
    labrecorder_markers: int  # how many markers LabRecorder's file holds


def named(streams: list[dict], name: str) -> dict:
    return next(s for s in streams if s["info"]["name"][0] == name)


def agreement(session: RecordedSession) -> Agreement:
    """Compare the recording with the participant's database (the offset between the stored rows'
    UTC times and the LSL clock is the one a :class:`ClockWatch` saw when the marker was pushed,
    measured independently of the product's mapping)."""
    store = ParticipantStore.open(session.study, session.code)
    try:
        stored = [e for e in store.events() if e.kind in MARKED]
    finally:
        store.close()
    rows = stored_samples(session.study, session.code)
    streams, _ = pyxdf.load_xdf(session.xdf, dejitter_timestamps=False)
    markers, robot = named(streams, session.markers), named(streams, session.robot)
    recorded = [decode(m[0]) for m in markers["time_series"]]
    utc = [datetime.fromisoformat(e.at).timestamp() for e in stored]
    marker_error = (max(float(np.abs(stamp - (at - offsets_around(session.offsets, stamp,
                                                                  PUSHED_WITHIN_S))).min())
                        for stamp, at in zip(markers["time_stamps"], utc, strict=True))
                    if len(utc) == len(recorded) else math.inf)
    go = {m["trial"]: stamp for m, stamp in zip(recorded, markers["time_stamps"], strict=True)
          if m["event"] == "go"}
    series, stamps = robot["time_series"], robot["time_stamps"]
    counts, robot_error, equal, steps = {}, 0.0, True, []
    for trial, mine in rows.items():
        mask = series[:, 0] == trial
        counts[trial] = (int(mask.sum()), len(mine["t"]))
        if counts[trial][0] != counts[trial][1] or trial not in go:
            robot_error, equal = math.inf, False
            continue
        robot_error = max(robot_error, float(np.abs(stamps[mask] - (go[trial] + mine["t"])).max()))
        expected = np.column_stack([mine[column].reshape(len(mine["t"]), -1)
                                    for column, _, _ in ROBOT_COLUMNS])
        equal = equal and np.array_equal(series[mask, 1:], expected, equal_nan=True)
        steps.extend(np.diff(stamps[mask]))
    theirs, _ = pyxdf.load_xdf(session.labrecorder)
    return Agreement(stored, recorded, marker_error, wall_clock_steps(session.offsets), counts,
                     robot_error, equal, 1.0 / float(np.median(steps)),
                     len(named(theirs, session.markers)["time_series"]))
