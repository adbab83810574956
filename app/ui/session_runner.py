"""The running session behind both screens: engine, controller and learner, no GUI (DESIGN.md §1).

One :class:`SessionRunner` owns the participant's :class:`SessionEngine`, runs each handover in real
time on the mock arm with the simulated hand (the loop in its own thread), and lets a background
worker ask the learner for the next θ and, when switched on, the simulated participant rate. Every
change is published as a :class:`RunnerView` — a consistent copy of the engine's state plus device
status — to the subscribed screens, which render nothing else. The engine (and its SQLite
connection, which belongs to one thread) is only touched on one engine thread, one call at a time;
:meth:`SessionRunner.stop` does not wait for it, so Stop reaches the arm whatever else is going on.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from app.learning.errors import LearningError
from app.learning.models import PosteriorSlice
from app.protocol.auto import step_once
from app.protocol.engine import SessionEngine, TrialPlan
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import SessionState, Step
from robot_io.config import ControllerConfig, SceneConfig
from robot_io.errors import RobotIOError
from robot_io.loop import HandoverLoop
from robot_io.mock_arm import MockArm
from robot_io.simulated_hand import Scenario, SimulatedHand
from robot_io.trial import make_clock, make_loop
from session_store.errors import RefusedAction, StoreError
from session_store.models import StudyConfig, Trial
from session_store.store import ParticipantStore, participant_codes

log = logging.getLogger(__name__)

#: How long the planner waits for the learner before it falls back to a flagged Sobol point [s].
PLAN_TIMEOUT_S = 60.0
#: The simulated participant's pause before it rates, so that each screen is seen [s].
AUTO_DELAY_S = 0.6
#: Stop: if the loop has not halted the arm within this time, the arm is stopped directly [s].
STOP_BACKSTOP_S = 0.5
#: The reasons recorded with a trial the experimenter aborted or stopped.
ABORT_REASON = "aborted by the experimenter"
STOP_REASON = "stopped by the experimenter (Stop)"
#: How many recent events the dashboard lists.
MESSAGES = 5


class ThetaStar(BaseModel):
    after_interaction: int
    a: float
    delta: float
    k: float


class RunnerView(BaseModel):
    """Everything a screen shows, copied at one moment. ``state`` is None before a session is open."""

    model_config = ConfigDict(frozen=True)

    version: int = 0
    code: str | None = None
    scenario: Scenario | None = None
    state: SessionState | None = None
    interactions: int = 0
    preparing: bool = False
    auto: bool = False
    arm: str = "mock arm: idle"
    arm_fault: str | None = None
    hand: str = "simulated hand"
    learner: str = "idle"
    learner_fault: str | None = None
    messages: list[str] = []  # the latest events, newest last
    trials: list[Trial] = []
    theta_star: list[ThetaStar] = []
    posterior: list[PosteriorSlice] = []  # posterior utility through θ*, per parameter

    @property
    def step(self) -> Step | None:
        return None if self.state is None else self.state.step


Listener = Callable[[RunnerView], None]
T = TypeVar("T")


class SessionRunner:
    """One participant at a time. Actions raise :class:`RefusedAction` with the reason."""

    def __init__(self, study: Path, rate_hz: int = 500, protocol: dict | None = None,
                 realtime_priority: bool = False) -> None:
        self.study = study
        self.rate_hz = rate_hz
        self.realtime_priority = realtime_priority
        self.protocol = protocol or {}
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="engine")
        self._engine_thread = self._executor.submit(threading.get_ident).result()
        self._engine: SessionEngine | None = None
        self._participant: SimulatedParticipant | None = None
        self._loop: HandoverLoop | None = None
        self._arm: MockArm | None = None
        self._plan: TrialPlan | None = None
        self._abort_reason: str | None = None
        self._auto = False
        self._preparing = False
        self._messages: deque[str] = deque(maxlen=MESSAGES)
        self._learner_fault: str | None = None
        self._theta_star: list[ThetaStar] = []
        self._theta_star_key = -1
        self._listeners: list[Listener] = []
        self._view = RunnerView()
        self._wake = threading.Event()
        self._closing = False
        self._worker = threading.Thread(target=self._work, name="session-worker", daemon=True)
        self._worker.start()

    # -- reading --------------------------------------------------------------------------------
    @property
    def view(self) -> RunnerView:
        """The latest published view (never blocks)."""
        return self._view

    def subscribe(self, listener: Listener) -> None:
        self._listeners.append(listener)

    def live(self, stride: int = 1) -> tuple[TrialPlan | None, dict[str, np.ndarray] | None]:
        """The running (or last) trial and its rows so far, for live displays (never blocks)."""
        loop = self._loop
        return self._plan, None if loop is None else loop.latest(stride)

    def scene_config(self) -> SceneConfig:
        """The geometry of the open session (the defaults before one is open)."""
        engine = self._engine
        return (ControllerConfig() if engine is None else engine.config.controller).scene

    def codes(self) -> list[str]:
        """The participants of the study folder."""
        return participant_codes(self.study) if self.study.exists() else []

    # -- the experimenter's actions ---------------------------------------------------------------
    def open(self, code: str, scenario: Scenario | None = None, seed: int = 0) -> None:
        """Resume ``code``'s session, or create it (with ``scenario``) if it has none."""
        def open_engine() -> None:
            if self._engine is not None:
                raise RefusedAction(f"participant {self._engine.participant.code!r} is open; "
                                    "close the server to switch participants")
            if ParticipantStore.exists(self.study, code):
                engine = SessionEngine.resume(self.study, code)
            elif scenario is None:
                raise RefusedAction(f"participant {code!r} has no session yet: choose a scenario "
                                    "to create one")
            else:
                engine = SessionEngine.create(self.study, code, self._study_config(scenario, seed))
            self._engine = engine
            self._participant = SimulatedParticipant(engine.config.seed)
            self._theta_star_key = -1
            log.info("session %s open at step %s", code, engine.state.step)

        self._call(open_engine)
        self._changed(f"participant {code} open")

    def start_trial(self) -> None:
        plan = self._call(self._start_trial)
        self._changed(f"trial {plan.trial.trial_index} started (interaction "
                      f"{plan.trial.interaction}, attempt {plan.trial.attempt})")

    def abort_trial(self) -> None:
        """End the running trial now; it is recorded as aborted and will be repeated."""
        if self._loop is None or self._loop.result is not None:
            raise RefusedAction("abort refused: no trial is running")
        self._halt(ABORT_REASON)

    def stop(self) -> None:
        """Stop the arm, whatever else is going on (never waits for the engine). A running trial
        is aborted."""
        self._halt(STOP_REASON)
        arm = self._arm
        if arm is not None:
            arm.stop()  # idempotent: a no-op for an arm already at rest
        # A Start being processed right now is stopped as soon as it has started the loop.
        self._executor.submit(self._halt, STOP_REASON)
        self._changed("Stop: the arm is stopped")

    def pause(self) -> None:
        self._call(lambda: self._require_engine().pause("paused by the experimenter"))
        self._changed("session paused")

    def resume(self) -> None:
        self._call(lambda: self._require_engine().resume_session())
        self._changed("session resumed")

    def set_auto(self, on: bool) -> None:
        self._auto = on
        self._changed(f"simulated participant {'on' if on else 'off'}")

    # -- the participant's actions (each names the interaction its screen showed) -----------------
    def place(self, interaction: int, position: float | None = None,
              equal_to: int | None = None) -> None:
        self._call(lambda: self._require_current(interaction, Step.PLACE).place(
            position=position, equal_to=equal_to))
        self._changed(None)

    def rate(self, interaction: int, rating: str) -> None:
        self._call(lambda: self._require_current(interaction, Step.RATE).rate_validation(rating))
        self._changed(None)

    def answer(self, question: str, value: str) -> None:
        self._call(lambda: self._require_engine().answer(question, value))
        self._changed(None)

    # -- shutdown ---------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the arm first (and wait for the loop), then close the engine and its store."""
        self._closing = True
        self._halt("session closed")
        loop = self._loop
        if loop is not None:
            loop.join(STOP_BACKSTOP_S + 2.0)
        if self._arm is not None:
            self._arm.stop()
        self._wake.set()
        self._call(self._close_engine)
        self._executor.shutdown()
        self._worker.join(2.0)

    # -- internals: on the engine thread ----------------------------------------------------------
    def _call(self, job: Callable[[], T]) -> T:
        """Run ``job`` on the engine thread and return its result (or raise its exception)."""
        if threading.get_ident() == self._engine_thread:
            return job()
        return self._executor.submit(job).result()

    def _start_trial(self) -> TrialPlan:
        engine = self._require_engine()
        plan = engine.start_trial()
        config = engine.config.controller
        clock = make_clock(config, realtime=True, realtime_priority=self.realtime_priority)
        hand = SimulatedHand(engine.config.scenario, config.scene, config.hand,
                             plan.trial.hand_seed)
        self._arm = MockArm(clock, config.scene.point("robot_start"))
        try:
            loop = make_loop(config, plan.theta, hand, self._arm, clock)
        except RobotIOError as exc:
            engine.end_trial(plan.trial.trial_index, None, f"could not start: {exc}")
            raise RefusedAction(f"the trial could not start: {exc}") from exc
        self._plan, self._loop, self._abort_reason = plan, loop, None
        loop.start()
        threading.Thread(target=self._finish_trial, args=(loop, plan), name="trial-watch",
                         daemon=True).start()
        return plan

    def _end_trial(self, loop: HandoverLoop, plan: TrialPlan) -> Trial | None:
        """Record the trial's end, unless it was already recorded."""
        engine = self._engine
        if engine is None or engine.state.running_trial != plan.trial.trial_index:
            return None
        return engine.end_trial(plan.trial.trial_index, loop.result, self._abort_reason)

    def _close_engine(self) -> None:
        if self._engine is None:
            return
        if self._loop is not None and self._plan is not None:
            self._end_trial(self._loop, self._plan)
        self._engine.close()
        self._engine = None

    def _study_config(self, scenario: Scenario, seed: int) -> StudyConfig:
        config = StudyConfig(scenario=scenario, seed=seed, **self.protocol)
        loop = config.controller.loop.model_copy(update={"rate_hz": self.rate_hz})
        return config.model_copy(update={"controller": config.controller.model_copy(
            update={"loop": loop})})

    def _require_engine(self) -> SessionEngine:
        if self._engine is None:
            raise RefusedAction("no participant is open: create or resume one first")
        return self._engine

    def _require_current(self, interaction: int, step: Step) -> SessionEngine:
        """The engine, if it still waits for ``step`` of ``interaction`` (a stale screen's action
        is refused, so a reload or a double tap never rates twice)."""
        engine = self._require_engine()
        slot = engine.state.slot
        if engine.state.step is not step or slot is None or slot.interaction != interaction:
            raise RefusedAction(f"refused: interaction {interaction} is not waiting for "
                                f"'{step.value}' (the session waits for "
                                f"'{engine.state.step.value}')")
        return engine

    def _make_view(self) -> RunnerView:
        engine, arm = self._engine, self._arm
        devices = {"arm": "mock arm: idle" if arm is None else f"mock arm: {arm.state.value}",
                   "arm_fault": None if arm is None else arm.fault,
                   "learner": "fitting the next θ" if self._preparing else "idle",
                   "learner_fault": self._learner_fault}
        if engine is None:
            return RunnerView(version=self._view.version + 1, auto=self._auto,
                              messages=list(self._messages), **devices)
        state = engine.state
        if self._theta_star_key != len(state.planned):  # a new θ means a new learner snapshot
            self._theta_star_key = len(state.planned)
            self._theta_star = [
                ThetaStar(after_interaction=r.after_interaction, a=r.theta_star_a,
                          delta=r.theta_star_delta, k=r.theta_star_k)
                for r in engine.store.rows("learner_snapshots") if r.theta_star_a is not None]
        return RunnerView(
            version=self._view.version + 1, code=engine.participant.code,
            scenario=engine.config.scenario, state=state.model_copy(deep=True),
            interactions=engine.config.interactions, preparing=self._preparing, auto=self._auto,
            hand=f"simulated hand ({engine.config.scenario.value})",
            messages=list(self._messages),
            trials=engine.store.rows("trials", order_by="trial_index"),
            theta_star=self._theta_star, posterior=engine.posterior_slices, **devices)

    # -- internals: other threads -----------------------------------------------------------------
    def _halt(self, reason: str) -> None:
        loop = self._loop
        if loop is None or loop.result is not None:
            return
        self._abort_reason = self._abort_reason or reason
        loop.request_stop()
        if loop.join(STOP_BACKSTOP_S) is None and self._arm is not None:
            log.error("the loop did not halt within %.1f s: stopping the arm directly",
                      STOP_BACKSTOP_S)
            self._arm.stop()

    def _finish_trial(self, loop: HandoverLoop, plan: TrialPlan) -> None:
        loop.join()
        if self._closing:
            return  # close() records it
        ended = self._call(lambda: self._end_trial(loop, plan))
        if ended is not None:
            self._changed(f"trial {ended.trial_index} {ended.outcome.value}"
                          + (f": {ended.reason}" if ended.reason else ""))

    def _changed(self, message: str | None) -> None:
        if message is not None:
            self._messages.append(f"{time.strftime('%H:%M:%S')} {message}")
            log.info("%s", message)
        self._publish()
        self._wake.set()

    def _publish(self) -> None:
        if self._closing:
            return
        view = self._view = self._call(self._make_view)
        for listener in list(self._listeners):
            try:
                listener(view)
            except Exception:
                log.exception("a screen failed to render")

    def _work(self) -> None:
        """The background worker: plans the next θ, and lets the simulated participant act."""
        while not self._closing:
            self._wake.wait()
            self._wake.clear()
            while not self._closing and self._next_job():
                pass

    def _next_job(self) -> bool:
        view = self._view
        if view.state is None:
            return False
        step = view.step
        if step is Step.PLAN:
            self._plan_next()
            return False
        if self._auto and step in (Step.PLACE, Step.RATE, Step.ANSWER):
            time.sleep(AUTO_DELAY_S)
            self._call(lambda: self._auto_step(step))
            self._changed("the simulated participant rated")
            return True
        return False

    def _auto_step(self, step: Step) -> None:
        if self._auto and self._engine is not None and self._engine.state.step is step:
            step_once(self._engine, self._participant)

    def _plan_next(self) -> None:
        self._preparing = True
        self._publish()
        try:
            planned = self._call(lambda: self._require_engine().plan_next(PLAN_TIMEOUT_S))
            self._learner_fault = ("the learner was late: a Sobol point was used (fallback)"
                                   if planned.fallback else None)
        except (LearningError, RefusedAction, StoreError) as exc:
            log.exception("planning the next θ failed")
            self._learner_fault = f"{type(exc).__name__}: {exc}"
        finally:
            self._preparing = False
            self._changed(None)
