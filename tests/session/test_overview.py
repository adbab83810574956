"""The study overview that the dashboard refreshes after every trial: each line is what a fresh
read of that participant's database says, a line whose database has not changed is not read again,
and the open session's line comes from the store it writes. The sessions stay in their first
(Sobol) trials of the briefest protocol."""

from __future__ import annotations

from pathlib import Path

from support.engine import brief_config, drive_until, step_once

from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.session.overview import SessionStatus, StudyOverview, summarise
from session_store.store import participant_codes


def first_trial(study: Path, code: str) -> SessionEngine:
    """``code``'s session of the briefest protocol, its first trial done and waiting for its
    placement."""
    engine = SessionEngine.create(study, code, brief_config())
    drive_until(engine, Step.PLACE)
    return engine


def next_trial(engine: SessionEngine) -> None:
    """Place the last trial, plan and run the next one."""
    participant = SimulatedParticipant(engine.config.seed)
    drive_until(engine, Step.READY, participant)
    step_once(engine, participant)


def fresh(study: Path, open_code: str | None = None) -> list:
    """Every line as a new read of every database gives it."""
    return [summarise(study, code, open_code) for code in participant_codes(study)]


def test_lines_are_fresh_reads_and_an_unchanged_participant_is_not_read_again(tmp_path: Path):
    study = tmp_path / "study"
    paused = first_trial(study, "P01")
    paused.pause("a break")
    paused.close()
    first_trial(study, "P02").close()
    overview = StudyOverview(study)
    first = overview.lines()
    assert first == fresh(study)
    assert [(line.code, line.status) for line in first] == [
        ("P01", SessionStatus.PAUSED), ("P02", SessionStatus.INTERRUPTED)]

    # another writer (here: this process, through the participant's own engine) continues P02
    engine = SessionEngine.resume(study, "P02")
    next_trial(engine)
    second = overview.lines()
    assert second == fresh(study)
    assert second[1].completed == first[1].completed + 1
    assert second[0] is first[0]  # P01's database did not change: its line was not read again

    engine.pause("the end")
    third = overview.lines()
    assert third == fresh(study)
    assert (third[1].status, third[1].detail) == (SessionStatus.PAUSED, "the end")
    assert third[0] is first[0]
    engine.close()


def test_the_open_sessions_line_comes_from_its_own_store(tmp_path: Path):
    study = tmp_path / "study"
    first_trial(study, "P01").close()
    engine = first_trial(study, "P02")
    overview = StudyOverview(study)
    lines = overview.lines(engine.store, "P02")
    assert lines == fresh(study, open_code="P02")
    assert (lines[1].status, lines[1].completed) == (SessionStatus.OPEN, 1)
    next_trial(engine)
    assert overview.lines(engine.store, "P02") == fresh(study, open_code="P02")
    assert overview.lines(engine.store, "P02")[1].completed == 2
    engine.close()
    assert overview.lines()[1].status is SessionStatus.INTERRUPTED
