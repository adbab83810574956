"""Property-based hunt for corruption (Hypothesis, stateful): random interleavings of the protocol's
actions, refused actions, kills (the engine reopened from the file at any point, its learner process
SIGKILLed) and pauses, on the short protocol with the real learner and real trials of the mock arm.

After every step: the state replayed from the file equals the live state; no interaction is
completed or placed twice; the completed trials in the tables are those of the state. A refused
action wrote nothing; a second writer is refused and wrote nothing.

Bounded: ``MAX_EXAMPLES`` sessions of up to ``STEPS`` steps, derandomized (tests/conftest.py).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import shutil
import signal
import sqlite3
import tempfile
from pathlib import Path

import pytest
from hypothesis import event, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule
from pydantic import ValidationError
from support.engine import short_config, step_once

from app.learning.worker import LearnerClient
from app.protocol.engine import SessionEngine
from app.protocol.errors import RefusedAction
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step, replay
from robot_io.control.trial import simulate_trial
from session_store.errors import ParticipantLocked
from session_store.vocabulary import QUESTIONS, Actor

MAX_EXAMPLES = 20
STEPS = 100
CODE = "H01"


class SessionMachine(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.folder = Path(tempfile.mkdtemp(prefix="hypothesis-session-"))
        self.engine: SessionEngine | None = None
        self.plan = None

    @initialize(seed=st.integers(0, 3))
    def create(self, seed: int) -> None:
        self.engine = SessionEngine.create(self.folder, CODE, short_config(seed=seed),
                                           LearnerClient.for_session)

    # -- the protocol's actions -----------------------------------------------------------------
    def _at(self, step: Step) -> bool:
        return self.engine is not None and self.engine.state.step is step

    @precondition(lambda self: self._at(Step.PLAN))
    @rule()
    def plan_next(self) -> None:
        self.engine.plan_next()

    @precondition(lambda self: self._at(Step.READY) and not self.engine.state.paused)
    @rule()
    def start(self) -> None:
        self.plan = self.engine.start_trial()

    @precondition(lambda self: self._at(Step.RUNNING))
    @rule(completes=st.booleans())
    def end(self, completes: bool) -> None:
        plan, self.plan = self.plan, None
        if completes:
            record = simulate_trial(self.engine.config.controller, plan.theta,
                                    self.engine.config.scenario, plan.trial.hand_seed)
            self.engine.end_trial(plan.trial.trial_index, record)
        else:
            self.engine.end_trial(plan.trial.trial_index, None, "aborted", Actor.EXPERIMENTER)

    @precondition(lambda self: self._at(Step.PLACE))
    @rule(position=st.floats(0.0, 1.0), tie=st.integers(0, 4))
    def place(self, position: float, tie: int) -> None:
        markers = self.engine.state.markers
        if markers and tie < len(markers):
            self.engine.place(equal_to=markers[tie].interaction)
        else:
            self.engine.place(position=position)

    @precondition(lambda self: self._at(Step.RATE))
    @rule(rating=st.sampled_from(["better", "worse", "equal"]))
    def rate(self, rating: str) -> None:
        self.engine.rate_validation(rating)

    @precondition(lambda self: self._at(Step.ANSWER))
    @rule(choice=st.integers(0, 4))
    def answer(self, choice: int) -> None:
        question = next(q for q in QUESTIONS if q.id not in self.engine.state.answers)
        allowed = question.allowed()
        self.engine.answer(question.id, allowed[choice % len(allowed)])

    @precondition(lambda self: self.engine is not None and not self.engine.state.paused
                  and self.engine.state.step not in (Step.RUNNING, Step.DONE))
    @rule()
    def pause(self) -> None:
        self.engine.pause("hypothesis")

    @precondition(lambda self: self.engine is not None and self.engine.state.paused)
    @rule()
    def resume_session(self) -> None:
        self.engine.resume_session()

    @precondition(lambda self: self.engine is not None
                  and self.engine.state.step is not Step.DONE)
    @rule(times=st.integers(1, 12))
    def advance(self, times: int) -> None:
        """The simulated participant and experimenter do what the session waits for, ``times``
        actions in a row (so that examples reach the later phases)."""
        participant = SimulatedParticipant(self.engine.config.seed)
        for _ in range(times):
            if self.engine.state.step is Step.DONE:
                return
            if self.engine.state.step is Step.RUNNING:
                self.end(completes=True)
            else:
                step_once(self.engine, participant)

    # -- what must not change anything ----------------------------------------------------------
    def _written(self) -> tuple:
        return (self.engine.store.counts(), self.engine.state.model_dump())

    @precondition(lambda self: self.engine is not None)
    @rule(data=st.data(), value=st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=5))
    def refused(self, data, value) -> None:
        """An action the state does not allow, or a bad value: refused, nothing written."""
        engine, state = self.engine, self.engine.state
        allowed = {"place": state.step is Step.PLACE, "rate": state.step is Step.RATE,
                   "answer": state.step is Step.ANSWER,
                   "start": state.step is Step.READY and not state.paused,
                   "pause": not state.paused and state.step not in (Step.RUNNING, Step.DONE),
                   "resume": state.paused, "plan": state.step in (Step.PLAN, Step.READY)}
        calls = {"place": lambda: engine.place(position=0.5),
                 "place_outside": lambda: engine.place(position=value if isinstance(value, float)
                                                       and not 0 <= value <= 1 else 2.0),
                 "rate_badly": lambda: engine.rate_validation(f"{value}?"),
                 "answer_badly": lambda: engine.answer("Q2", f"{value}?"),
                 "rate": lambda: engine.rate_validation("better"),
                 "answer": lambda: engine.answer("Q1", "3"),
                 "start": engine.start_trial,
                 "end_another": lambda: engine.end_trial((state.running_trial or 0) + 7, None),
                 "pause": engine.pause, "resume": engine.resume_session, "plan": engine.plan_next}
        action = data.draw(st.sampled_from(sorted(a for a in calls if not allowed.get(a, False))))
        event(f"refused: {action}")
        before = self._written()
        with pytest.raises((RefusedAction, ValidationError)):
            calls[action]()
            pytest.fail(f"{action} was not refused at step {state.step.value}, paused "
                        f"{state.paused}")
        assert self._written() == before

    @precondition(lambda self: self.engine is not None)
    @rule()
    def second_writer(self) -> None:
        before = self._written()
        with pytest.raises(ParticipantLocked, match="open for writing by pid"):
            SessionEngine.resume(self.folder, CODE, LearnerClient.for_session)
        assert self._written() == before

    @precondition(lambda self: self.engine is not None)
    @rule()
    def kill(self) -> None:
        """A crash at this point: the learner process is SIGKILLed, the engine and its connection
        are gone; only what was committed survives. Then the session is reopened from the file."""
        if self.engine.learner.pid is not None:
            os.kill(self.engine.learner.pid, signal.SIGKILL)
        self.engine.close()
        self.plan = None
        self.engine = SessionEngine.resume(self.folder, CODE, LearnerClient.for_session)

    # -- after every step ------------------------------------------------------------------------
    @invariant()
    def the_file_replays_to_the_live_state(self) -> None:
        if self.engine is None:
            return
        replayed = replay(self.engine.slots, self.engine.store.events())
        assert replayed.model_dump() == self.engine.state.model_dump()

    @invariant()
    def nothing_is_completed_or_placed_twice(self) -> None:
        if self.engine is None:
            return
        conn: sqlite3.Connection = self.engine.store.db.conn
        completed = conn.execute("SELECT interaction, trial_index FROM trials WHERE outcome = "
                                 "'completed' ORDER BY interaction").fetchall()
        assert dict(completed) == self.engine.state.completed_trial
        assert len({i for i, _ in completed}) == len(completed)
        placed = [i for (i,) in conn.execute("SELECT interaction FROM placements")]
        assert len(placed) == len(set(placed))

    def teardown(self) -> None:
        if self.engine is not None:
            event(f"ended at step {self.engine.state.step.value}, "
                  f"{self.engine.state.completed} completed")
            self.engine.close()
        shutil.rmtree(self.folder, ignore_errors=True)


mp.set_forkserver_preload(["app.learning.learner", "app.learning.worker"])
SessionMachine.TestCase.settings = settings(max_examples=MAX_EXAMPLES, stateful_step_count=STEPS)


@pytest.mark.slow
class TestSessionEngine(SessionMachine.TestCase):
    """Slow: MAX_EXAMPLES sessions of up to STEPS steps, each step a real trial of the mock arm or a
    learner's batch, a kill and a reopening from the file; the invariants replay the file each step."""
