"""A short session on the wall clock whose LSL outlets are recorded to XDF, as a lab records them:
the study's robot and marker streams beside a stand-in eye tracker's pupil diameter
(support/pupil.py), by the suite's own recorder (support/xdf_recorder.py, which the session waits
on before it stops it) and by a real LabRecorder. tests/session/test_lsl_outlets.py checks the
recording against the SQLite rows; tests/analysis/test_xdf_report.py runs ``report --xdf`` on it.
Both use the session-scoped fixture ``recorded_session`` (tests/conftest.py) in one xdist group,
:data:`XDIST_GROUP`, so the session runs once per run.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.analysis.xdf import WINDOW_S
from app.protocol.markers import MARKED, decode
from app.protocol.state import Step
from app.session.config import LabConfig
from app.session.replay import stored_rows
from app.session.runner import SessionRunner
from robot_io.simulated_hand import Scenario
from session_store.store import ParticipantStore
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


def run_trials(runner: SessionRunner, probe: Probe) -> None:
    """Start each trial when the session is ready for it, until it is done."""
    for _ in range(6):  # two trials, and a few repeats should one not complete
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


def record_session(folder: Path) -> RecordedSession:
    """Run the session with the recorders on; return once both files are written."""
    name = f"test-{uuid.uuid4().hex[:12]}"  # stream names of this run's own
    markers, robot, pupil = f"{name}-markers", f"{name}-robot", f"{name}-pupil"
    lab = LabConfig.model_validate({"loop": {"rate_hz": RATE_HZ}, "protocol": PROTOCOL,
                                    "record": {"lsl_name": name}})
    runner = SessionRunner(folder / "study", lab, realtime_priority=True)
    probe = Probe(runner)
    runner.set_auto(True)
    tracker = theirs = None
    try:
        runner.open(CODE, Scenario.STRAIGHTFORWARD, seed=4)  # the outlets open with the participant
        tracker = PupilTracker(pupil, robot)
        names = [markers, robot, pupil]
        ours = XDFRecorder(folder / "session.xdf", names)
        theirs = LabRecorder(folder / "labrecorder.xdf", names)
        run_trials(runner, probe)
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
    return RecordedSession(folder / "study", CODE, RATE_HZ, markers, robot, pupil, xdf, labrecorder)
