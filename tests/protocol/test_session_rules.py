"""Bad input is refused with a clear message and writes nothing; the store refuses bad files;
a session resumes where it stopped."""

from __future__ import annotations

import sqlite3
from typing import get_args

import numpy as np
import pytest
from pydantic import ValidationError
from support.engine import drive_until, new_engine, short_config

from app.protocol import events as ev
from app.protocol.engine import SessionEngine
from app.protocol.errors import EventLogError, RefusedAction
from app.protocol.plan import protocol_slots
from app.protocol.state import HANDLERS, WAITS_FOR, SessionState, Step, apply, refusal
from app.protocol.study_config import StudyConfig
from robot_io.control.trial import simulate_trial
from robot_io.hands.simulated_hand import Scenario
from session_store.errors import (
    CorruptStoreError,
    SchemaVersionError,
    StoreError,
    UnsafeParticipantCode,
)
from session_store.store import ParticipantStore
from session_store.vocabulary import Actor


@pytest.fixture
def engine(tmp_path):
    engine = new_engine(tmp_path)
    yield engine
    engine.close()


def snapshot(engine: SessionEngine) -> dict:
    return engine.store.counts()


@pytest.mark.parametrize("code", ["../x", "", "a" * 300, "a/b", ".hidden", "P 01", "Bob\x00"])
def test_unsafe_participant_codes_are_refused_and_nothing_is_written(tmp_path, code):
    with pytest.raises(UnsafeParticipantCode, match="is not allowed"):
        SessionEngine.create(tmp_path / "study", code, short_config())
    assert not (tmp_path / "study").exists() or not any((tmp_path / "study").iterdir())
    assert not (tmp_path / "x.sqlite").exists()


def test_a_placement_for_an_aborted_trial_is_refused(engine):
    drive_until(engine, Step.READY)
    plan = engine.start_trial()
    engine.end_trial(plan.trial.trial_index, None, "experimenter abort")
    before = snapshot(engine)
    with pytest.raises(RefusedAction, match="waits for 'ready', not 'place'"):
        engine.place(position=0.5)
    assert snapshot(engine) == before
    aborted = engine.store.rows("trials")[-1]
    assert aborted.outcome == "aborted" and aborted.reason == "experimenter abort"
    # the aborted interaction is repeated with the same θ and the same simulated hand
    again = engine.start_trial()
    assert again.trial.interaction == plan.trial.interaction and again.trial.attempt == 2
    assert again.theta == plan.theta and again.trial.hand_seed == plan.trial.hand_seed


def test_a_failed_handover_counts_as_aborted_and_is_repeated(engine):
    drive_until(engine, Step.READY)
    plan = engine.start_trial()
    config = engine.config.controller.model_copy(update={
        "loop": engine.config.controller.loop.model_copy(update={"timeout_s": 0.3})})
    record = simulate_trial(config, plan.theta, engine.config.scenario, plan.trial.hand_seed)
    ended = engine.end_trial(plan.trial.trial_index, record)
    assert ended.outcome == "aborted" and ended.reason.startswith("timeout")
    assert engine.state.step is Step.READY and engine.state.completed == 0
    assert len(engine.store.samples(plan.trial.trial_index)) == record.summary.cycles


@pytest.mark.parametrize("position,equal_to,message", [
    (1.5, None, r"position = 1.5 is outside the scale \[0.0, 1.0\]"),
    (-0.1, None, r"position = -0.1 is outside the scale"),
    (None, None, r"position = None is outside the scale"),
    (None, 42, r"equal_to = 42 is not an interaction on the scale of this batch"),
])
def test_bad_placements_are_refused_and_nothing_is_written(engine, position, equal_to, message):
    drive_until(engine, Step.PLACE)
    before = snapshot(engine)
    with pytest.raises(RefusedAction, match=message):
        engine.place(position=position, equal_to=equal_to)
    assert snapshot(engine) == before


@pytest.mark.parametrize("question,value,message", [
    ("Q1", "7", r"answer to Q1 = '7' is not one of \['1', '2', '3', '4', '5'\]"),
    ("Q2", "Sometimes", r"answer to Q2 = 'Sometimes' is not one of \['Yes', 'No', 'Maybe'\]"),
    ("Q4", "1", r"question = 'Q4' is not one of"),
])
def test_answers_out_of_range_are_refused_and_nothing_is_written(engine, question, value, message):
    drive_until(engine, Step.ANSWER)
    before = snapshot(engine)
    with pytest.raises(ValidationError, match=message):
        engine.answer(question, value)
    assert snapshot(engine) == before
    engine.answer("Q1", "4")
    with pytest.raises(RefusedAction, match="Q1 is already answered"):
        engine.answer("Q1", "5")


def test_pause_blocks_the_next_trial_until_resumed(engine):
    drive_until(engine, Step.READY)
    engine.pause("participant needs a break")
    with pytest.raises(RefusedAction, match="paused"):
        engine.start_trial()
    engine.resume_session()
    assert engine.start_trial().trial.interaction == 1


def test_a_session_resumed_mid_trial_records_the_abort_and_repeats_it(tmp_path):
    engine = new_engine(tmp_path)
    drive_until(engine, Step.READY)
    plan = engine.start_trial()
    engine.close()  # the process dies here, mid-trial
    resumed = SessionEngine.resume(tmp_path, "S01")
    try:
        first = resumed.store.rows("trials")[0]
        assert first.outcome == "aborted" and first.reason == "session interrupted"
        assert resumed.state.step is Step.READY
        assert resumed.start_trial().theta == plan.theta
        kinds = [e.kind for e in resumed.store.events()]
        assert kinds.count("session_resumed") == 1
    finally:
        resumed.close()


def test_creating_an_existing_participant_is_refused(tmp_path):
    new_engine(tmp_path).close()
    with pytest.raises(StoreError, match="already has a database"):
        new_engine(tmp_path)


def test_a_database_of_a_newer_schema_is_refused(tmp_path):
    new_engine(tmp_path).close()
    with sqlite3.connect(tmp_path / "S01.sqlite") as conn:
        conn.execute("PRAGMA user_version = 99")
    with pytest.raises(SchemaVersionError, match=r"schema version 99.*update handover-lab"):
        ParticipantStore.open(tmp_path, "S01")


def test_a_corrupt_or_foreign_file_is_refused(tmp_path):
    (tmp_path / "C01.sqlite").write_bytes(b"this is not a database" * 100)
    with pytest.raises(CorruptStoreError, match="not a readable SQLite database"):
        ParticipantStore.open(tmp_path, "C01")
    with sqlite3.connect(tmp_path / "F01.sqlite") as conn:
        conn.execute("CREATE TABLE cats (name TEXT)")
    with pytest.raises(SchemaVersionError, match="not a handover-lab database"):
        ParticipantStore.open(tmp_path, "F01")


def test_study_config_refuses_bounds_outside_table_i():
    with pytest.raises(ValidationError, match=r"theta_bounds.k = \[0.01, 20.0\] must lie within"):
        StudyConfig(scenario=Scenario.PERTURBED, theta_bounds={"a": (1, 10), "delta": (-1, 1),
                                                                "k": (0.01, 20.0)})


def test_forward_migrations_run_once_and_a_failing_one_changes_nothing(tmp_path, monkeypatch):
    from session_store import schema, store

    new_engine(tmp_path).close()

    def add_notes(db) -> None:
        db["trials"].add_column("notes", str)

    n = schema.SCHEMA_VERSION
    monkeypatch.setattr(store, "MIGRATIONS", {**schema.MIGRATIONS, n + 1: add_notes})
    monkeypatch.setattr(store, "SCHEMA_VERSION", n + 1)
    migrated = ParticipantStore.open(tmp_path, "S01")
    assert migrated.db.execute("PRAGMA user_version").fetchone()[0] == n + 1
    assert "notes" in migrated.db["trials"].columns_dict
    migrated.close()
    ParticipantStore.open(tmp_path, "S01").close()  # already there: nothing runs again

    def broken(db) -> None:
        db["trials"].add_column("half_done", str)
        raise RuntimeError("migration bug")

    monkeypatch.setattr(store, "MIGRATIONS", {**schema.MIGRATIONS, n + 1: add_notes, n + 2: broken})
    monkeypatch.setattr(store, "SCHEMA_VERSION", n + 2)
    with pytest.raises(RuntimeError, match="migration bug"):
        ParticipantStore.open(tmp_path, "S01")
    with sqlite3.connect(tmp_path / "S01.sqlite") as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == n + 1
        columns = [row[1] for row in conn.execute("PRAGMA table_info(trials)")]
    assert "half_done" not in columns


def test_the_engine_hands_the_dashboard_the_posterior_slices(engine):
    assert engine.posterior_slices == []
    for position in (0.3, 0.7, 0.5):  # the initial batch: its placements give comparisons
        drive_until(engine, Step.PLACE)
        engine.place(position=position)
    engine.plan_next()
    slices = engine.posterior_slices
    assert [s.parameter for s in slices] == ["a", "delta", "k"]
    for s in slices:
        low, high = engine.config.theta_bounds[s.parameter]
        assert (s.values[0], s.values[-1]) == (low, high)
        assert all(np.isfinite(s.mean))


def test_a_first_theta_the_learner_is_late_with_is_a_flagged_fallback_and_the_session_resumes(tmp_path):
    """A fresh learner that has not replied yet (its process still starting: under load it took
    over a minute) gives a flagged fallback θ for interaction 1. Planning it once crashed the
    engine (the learner had no state to store: AttributeError) and left a session stuck at 'plan'.
    With no snapshot stored, a resume starts the learner fresh, as the live one was."""
    engine = new_engine(tmp_path)
    try:
        planned = engine.plan_next(timeout=0.0)  # no wait: the learner cannot have replied
        assert engine.state.step is Step.READY and planned.fallback
        assert engine.store.rows("learner_snapshots") == []
        drive_until(engine, Step.PLACE)
        engine.place(position=0.5)
    finally:
        engine.close()
    resumed = SessionEngine.resume(tmp_path, "S01")
    try:
        drive_until(resumed, Step.PLACE)  # interaction 2's θ from the restored (fresh) learner
        assert resumed.state.planned[2].theta is not None
    finally:
        resumed.close()


def test_every_event_has_its_rule_and_one_without_is_an_event_log_error_not_a_key_error():
    """One place decides what an event may do (app.protocol.state): every kind of event has its
    handler, and an event no handler takes is reported as a log that breaks the protocol, naming
    it, never as the KeyError of a missing dictionary entry."""
    assert set(HANDLERS) == set(get_args(get_args(ev.ProtocolEvent)[0]))

    class Surprise(ev.Paused):
        """An event of a kind the protocol has no rule for (a newer application's, say)."""

    state = SessionState(slots=protocol_slots(short_config()))
    with pytest.raises(EventLogError, match=r"event 7 \(paused\): no rule of the protocol takes a "
                                            r"Surprise event"):
        apply(state, Surprise(seq=7, actor=Actor.EXPERIMENTER))


def test_the_engine_refuses_what_the_log_would_refuse_in_the_same_words(engine):
    """The step an event needs is one rule (WAITS_FOR): the engine's refusal and the stored log's
    breach name the same steps."""
    drive_until(engine, Step.READY)
    with pytest.raises(RefusedAction, match="refused: the session waits for 'ready', not 'answer'"):
        engine.answer("Q1", "4")
    breach = ev.AnswerGiven(seq=5, actor=Actor.PARTICIPANT, question="Q1", value="4")
    with pytest.raises(EventLogError, match="an answer to Q1 while the session waits for 'ready'"):
        apply(engine.state.model_copy(deep=True), breach)
    assert refusal(engine.state, ev.AnswerGiven) == "the session waits for 'ready', not 'answer'"
    assert WAITS_FOR[ev.AnswerGiven] is Step.ANSWER
