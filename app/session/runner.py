"""The running session behind both screens and the headless command (docs/controller.md, the rig process).

One :class:`SessionRunner` owns the participant's :class:`SessionEngine` and the rig process that
runs each trial's handover cycle on the configured devices (:class:`~robot_io.rig.client.RigClient`);
``handover serve`` renders it on the tablet and the dashboard, ``handover run-session`` drives it
headless, so both run the same trials on the same devices. A background worker asks the learner for
the next θ and, when switched on, lets the simulated participant rate (and, headless, the simulated
experimenter start each trial). Every change is published as a :class:`RunnerView` — a consistent copy
of the engine's state plus device status — to the subscribed screens, which render nothing else.

The engine (and its SQLite connection, which belongs to one thread) is only touched on one engine
thread, one call at a time. :meth:`SessionRunner.stop` never waits for it: it goes straight to the rig
(and past it, to the controller, if the rig does not answer), so Stop reaches the arm whatever else is
going on.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

import numpy as np

from app.learning.errors import LearningError
from app.learning.worker import warm_up
from app.protocol.auto import rate_once
from app.protocol.engine import RIG_TABLES, SessionEngine, TrialPlan, rig_of
from app.protocol.errors import RefusedAction
from app.protocol.recorded import describe_change, recorded_session
from app.protocol.seeds import choose_seed
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import PARTICIPANT_STEPS, Step
from app.protocol.study import StudyConfig
from app.protocol.vocabulary import Actor, Rater
from app.session import faults
from app.session.access import TABLET_BROWSER_FILE, KnownBrowsers
from app.session.config import LabConfig
from app.session.drawing import with_links
from app.session.faults import StagedFault
from app.session.lsl_outlets import StudyOutlets
from app.session.overview import ParticipantSummary, StudyOverview
from app.session.pairing import TabletPairing
from app.session.rehearsal import Rehearsal, rehearsal_rig
from app.session.replay import stored_rows
from app.session.view import (
    RigStatus,
    RunnerView,
    SessionFacts,
    Status,
    StopState,
    ThetaStar,
    Waiting,
    build_view,
    with_news,
)
from robot_io.clock import utc_of_monotonic
from robot_io.config import ControllerConfig, SceneConfig
from robot_io.cycle import not_started
from robot_io.errors import RobotIOError, explain
from robot_io.loop import Outcome, TrialRecord
from robot_io.rig.client import RigClient
from robot_io.rig.messages import (
    DeviceReport,
    HandLink,
    ReadyWaiting,
    Report,
    RigDied,
    RigSpec,
    RigTiming,
    RunTrial,
    StageReached,
    TrialDone,
)
from robot_io.simulated_hand import Scenario
from robot_io.stages import Stage
from session_store import lock as writer_lock
from session_store.errors import StoreError, StoreWriteError
from session_store.models import Trial
from session_store.paths import refuse_case_twin
from session_store.store import ParticipantStore, participant_codes, participant_path

log = logging.getLogger(__name__)

#: How long the planner waits for the learner before it falls back to a flagged Sobol point [s].
PLAN_TIMEOUT_S = 60.0
#: The simulated participant's pause before it rates, so that each screen is seen [s].
AUTO_DELAY_S = 0.6
#: The reasons recorded with a trial the experimenter aborted or stopped.
ABORT_REASON = "aborted by the experimenter"
STOP_REASON = "stopped by the experimenter (Stop)"
#: The reason recorded with a trial still running when the session closes (serve's Ctrl-C).
CLOSE_REASON = "session closed"
#: The reason recorded with the pause of a session the experimenter ended before it was complete,
#: and with its resume when the experimenter opens the participant again.
END_REASON = "ended by the experimenter"
REOPEN_REASON = "opened again by the experimenter"
#: How many recent events the dashboard lists.
MESSAGES = 5
#: The simulated experimenter gives up after this many trials in a row that did not complete.
MAX_FAILED_TRIALS = 5

Listener = Callable[[RunnerView], None]
T = TypeVar("T")


class SessionRunner:
    """One participant at a time, on the devices of ``lab`` (or of the ``rehearsal``, which the
    runner then owns). Actions raise :class:`RefusedAction` with the reason.

    ``realtime=False`` runs trials on simulated time (only the mock arm with the simulated hand);
    ``auto_experimenter`` starts every trial by itself (headless sessions)."""

    def __init__(self, study: Path, lab: LabConfig, *, realtime: bool = True,
                 realtime_priority: bool = False, rehearsal: Rehearsal | None = None,
                 auto_experimenter: bool = False) -> None:
        self.study = study
        self.rehearsal = rehearsal
        self.lab = rehearsal.lab if rehearsal is not None else lab
        self.realtime = realtime
        self.realtime_priority = realtime_priority
        self.auto_experimenter = auto_experimenter
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="engine")
        self._engine_thread = self._executor.submit(threading.get_ident).result()
        self._engine: SessionEngine | None = None
        self._participant: SimulatedParticipant | None = None
        self._rig: RigClient | None = None
        self._outlets: StudyOutlets | None = None  # the open session's LSL outlets ([record])
        self._devices: DeviceReport | None = None
        self._rig_fault: str | None = None
        self._timing: RigTiming | None = None  # the latest late timing, until a trial runs on time
        self._hand_link: str | None = None
        self._plan: TrialPlan | None = None
        self._abort_reason: str | None = None
        self._abort_actor = Actor.SYSTEM
        self._lock: writer_lock.WriterLock | None = None
        self._ready_wait: str | None = None
        self._auto = False
        self._blind: bool | None = None  # the dashboard's validation blinding; None: no dashboard
        self._refusing_object = False
        self._preparing = False
        self._failed_in_a_row = 0
        self._failed: str | None = None
        self._store_fault: str | None = None  # a write to the study failed: the session stops
        self._messages: deque[str] = deque(maxlen=MESSAGES)
        self._learner_fault: str | None = None
        self._theta_star: list[ThetaStar] = []
        self._theta_star_key = -1
        self._stop: StopState = "armed"
        self._pairing: TabletPairing | None = None
        self._overview: list[ParticipantSummary] | None = None  # None: to be read again
        self._study_overview = StudyOverview(self.study)
        self._listeners: list[Listener] = []
        self._view = RunnerView()
        # Views are made on the engine thread, numbered in the order they were made, and shown
        # under one lock; a view made earlier than the one already shown is dropped (two threads
        # publishing at once could otherwise show the older last: a dashboard stuck at "starting"
        # with the trial's stage already stored, and Object loaded never enabled).
        self._made = itertools.count(1)
        self._showing = threading.RLock()
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
        """The running (or last) trial and its rows so far with the arm's links
        (:func:`~app.session.drawing.with_links`), for live displays (never blocks)."""
        rig = self._rig
        if rig is None or self._plan is None or rig.stream.trial_index != self._plan.trial.trial_index:
            return self._plan, None
        return self._plan, with_links(rig.stream.view(stride))

    def scene_config(self) -> SceneConfig:
        """The geometry of the open session (the lab's before one is open)."""
        engine = self._engine
        return (self.lab if engine is None else engine.config.controller).scene

    def codes(self) -> list[str]:
        """The participants of the study folder."""
        return participant_codes(self.study) if self.study.exists() else []

    @property
    def rig(self) -> RigClient | None:
        return self._rig

    def trial_rows(self, trial_index: int) -> dict[str, np.ndarray]:
        """A stored trial of the open participant, as the live view's columns with the arm's links
        (for a replay); refused while a trial runs."""
        def read() -> dict[str, np.ndarray]:
            engine = self._require_engine()
            if engine.state.running_trial is not None:
                raise RefusedAction("replay refused while a trial runs")
            if not any(t.trial_index == trial_index for t in engine.store.rows("trials")):
                raise RefusedAction(f"trial {trial_index} is not a trial of "
                                    f"{engine.participant.code}")
            rows = stored_rows(engine.store.samples(trial_index))
            if len(rows["t"]) < 2:
                raise RefusedAction(f"trial {trial_index} has no recorded samples to replay")
            return with_links(rows)
        return self._call(read)

    # -- the tablet (one per session) -------------------------------------------------------------
    def attach_tablet(self) -> TabletPairing:
        """The tablet screen's pairing: from now on a trial starts only with exactly one paired
        tablet open (the simulated participant on a simulated rig excepted)."""
        self._pairing = TabletPairing(known=KnownBrowsers(self.study, TABLET_BROWSER_FILE))
        self._publish()
        return self._pairing

    def tablet_connected(self, page: int, address: str, browser: str | None = None) -> None:
        """A page opened on the tablet port from ``address``, in ``browser`` (its id, if known)."""
        again = self._pairing.connected(page, address, browser)
        self._changed_now("the tablet is paired again (the browser paired before)" if again
                          else None)

    def tablet_closed(self, page: int) -> None:
        self._pairing.closed(page)
        self._changed_now(None)

    def pair_tablet(self, page: int, code: str) -> str | None:
        """The code typed on a tablet page: None if it is now the study's tablet, else why not."""
        before = self._pairing.status()
        refusal = self._pairing.pair(page, code)
        after = self._pairing.status()
        if refusal is None and before.address not in (None, after.address):
            message = f"the tablet was taken over: from {before.address} to {after.address}"
        elif refusal is None:
            message = "the tablet is paired"
        elif after.code != before.code:
            message = f"{after.wrong_codes} wrong pairing codes: the code was replaced"
        else:
            message = None
        self._changed_now(message)
        return refusal

    @property
    def tablet_required(self) -> bool:
        """Whether a trial needs the paired tablet: always with a tablet screen, except when the
        simulated participant rates on a simulated rig (mock arm or rehearsal)."""
        simulated_rig = self.rehearsal is not None or self.lab.arm.kind == "mock"
        return self._pairing is not None and not (self._auto and simulated_rig)

    # -- the experimenter's actions ---------------------------------------------------------------
    def open(self, code: str, scenario: Scenario | None = None, seed: int | None = None,
             confirm_rig_change: bool = False, confirm_seed_reuse: bool = False) -> None:
        """Resume ``code``'s session, or create it (with ``scenario``) if it has none. Refused at
        once while another writer holds the participant. A new session gets ``seed`` (a fresh
        random one when None; one another participant has only with ``confirm_seed_reuse``). The
        rig is opened first; a session recorded on a different rig is refused unless
        ``confirm_rig_change``, and then the change is recorded."""
        self._call(lambda: self._open(code, scenario, seed, confirm_rig_change, confirm_seed_reuse))
        self._changed(f"participant {code} open on {self._devices.arm_detail}")

    def start_trial(self) -> None:
        plan = self._call(self._start_trial)
        self._changed(f"trial {plan.trial.trial_index} started (interaction "
                      f"{plan.trial.interaction}, attempt {plan.trial.attempt})")

    def object_loaded(self) -> None:
        """The experimenter confirms the object is in the gripper."""
        self._require_waiting("loaded").object_loaded()
        self._changed("object loaded")

    def go(self) -> None:
        """The experimenter gives Go: the tablet's cue and the robot's start."""
        self._require_waiting("go").go()
        self._changed("Go")

    def recover_arm(self, inspected: bool = True) -> None:
        """Clear the arm's fault once its cause is inspected (moves nothing); a UR's protective stop
        is unlocked no sooner than 5 s after it happened. When the rig process has ended (its
        fault), a fresh one is opened: it connects to the devices and moves nothing."""
        rig = self._rig
        if rig is None or not rig.alive:
            self._call(lambda: self._open_rig(self._require_engine().config))
            self._changed(f"a fresh rig process is open on {self._devices.arm_detail}")
            return
        if rig.running is not None:
            raise RefusedAction("recover refused while a trial runs: Stop it first")
        try:
            result = rig.recover(inspected)
        except RobotIOError as exc:
            raise RefusedAction(str(exc)) from exc
        if not result.ok:
            raise RefusedAction(result.message)
        self._rig_fault = None
        self._changed(result.message)

    def abort_trial(self) -> None:
        """End the running trial now; it is recorded as aborted and will be repeated."""
        if self._plan is None or self._rig is None or self._rig.running is None:
            raise RefusedAction("abort refused: no trial is running")
        self._halt(ABORT_REASON)

    def stop(self) -> None:
        """Stop the arm, whatever else is going on (never waits for the engine). A running trial
        is aborted. Start stays locked until :meth:`rearm`."""
        self._stop = "stopping"  # before the rig is told: its trial's end makes it "stopped"
        self._halt(STOP_REASON)  # first: nothing here waits for the engine thread
        if self._rig is None or self._rig.running is None:
            self._stop = "stopped"
        self._changed_now("Stop: the arm is stopped" if self._stop == "stopped" else
                          "STOP ARM: the arm is stopping")

    def rearm(self) -> None:
        """The experimenter confirms the scene is safe after a stop: trials may start again."""
        if self._stop == "stopping":
            raise RefusedAction("re-arm refused: the arm is still stopping")
        if self._stop == "armed":
            raise RefusedAction("re-arm refused: the arm was not stopped")
        self._stop = "armed"
        self._changed_now("re-armed: the experimenter confirmed the scene is safe")

    def end_session(self) -> None:
        """End the open participant's session (paused if it is not complete, so it resumes where
        it was) and close its rig, so that another participant can be opened."""
        code = self._call(self._end_session)
        self._changed(f"session of {code} ended")

    def pause(self) -> None:
        self._call(lambda: self._require_engine().pause("paused by the experimenter"))
        self._changed("session paused")

    def resume(self) -> None:
        self._call(lambda: self._require_engine().resume_session())
        self._changed("session resumed")

    def set_auto(self, on: bool) -> None:
        """Switch the simulated participant on or off; recorded in the open session (and in the
        next one opened), so that every rating's origin is known. Published at once; the record is
        written in order on the engine thread, without waiting for it (a screen's refresh may call
        this)."""
        self._auto = on
        self._executor.submit(self._record, "the simulated participant's switch",
                              lambda engine: engine.switch_simulated_participant(on))
        self._changed_now(f"simulated participant {'on' if on else 'off'}")

    def set_blinding(self, blind: bool) -> None:
        """The dashboard hides the θ and origin of validation trials (``blind``, the paper's blind
        validation) or shows them (pilots, debugging); recorded in the open session and in every
        one opened later, so each session says how its validation was run."""
        self._blind = blind
        self._executor.submit(self._record, "the validation's blinding",
                              lambda engine: engine.set_blinding(blind))

    def stage_fault(self, fault: StagedFault) -> None:
        """A rehearsal stages ``fault`` now (see :mod:`app.session.faults`); refused on the rig."""
        self._changed_now(faults.stage(fault, self.rehearsal, self._rig))

    def refuse_object(self, refuse: bool) -> None:
        """A rehearsal's simulated participant stops (or starts again) taking the object."""
        message = faults.refuse_object(self.rehearsal, refuse)
        self._refusing_object = refuse
        self._changed_now(message)

    # -- the participant's actions (each names the interaction its screen showed) -----------------
    # ``by``: the participant on the tablet, or the experimenter entering it for them (dashboard)
    def place(self, interaction: int, position: float | None = None,
              equal_to: int | None = None, by: Rater = Rater.PARTICIPANT) -> None:
        self._call(lambda: self._require_current(interaction, Step.PLACE).place(
            position=position, equal_to=equal_to, by=by))
        self._changed(None)

    def rate(self, interaction: int, rating: str, by: Rater = Rater.PARTICIPANT) -> None:
        self._call(lambda: self._require_current(interaction, Step.RATE).rate_validation(
            rating, by=by))
        self._changed(None)

    def answer(self, question: str, value: str, by: Rater = Rater.PARTICIPANT) -> None:
        self._call(lambda: self._require_engine().answer(question, value, by=by))
        self._changed(None)

    # -- shutdown ---------------------------------------------------------------------------------
    def close(self, reason: str = CLOSE_REASON) -> None:
        """Stop the arm first, then close the rig, the engine and its store, and the rehearsal; a
        running trial is recorded aborted with ``reason``. Closing twice does nothing more."""
        if self._closing:
            return
        self._closing = True
        rig = self._rig
        if rig is not None:
            if rig.running is not None:
                self._abort_reason = self._abort_reason or reason
                rig.stop(reason)
            rig.close()
            if not rig.reports_handed_on():  # the stopped trial's end is recorded before the engine closes
                log.error("the rig's last reports were not all handed on: a trial left running is "
                          "recorded aborted when the session resumes")
        self._wake.set()
        self._call(self._close_engine)
        self._executor.shutdown()
        self._worker.join(2.0)
        if self.rehearsal is not None:
            self.rehearsal.close()

    # -- internals: on the engine thread ----------------------------------------------------------
    def _call(self, job: Callable[[], T]) -> T:
        """Run ``job`` on the engine thread and return its result (or raise its exception; a
        failed write to the study stops the session, see :meth:`_storage_failed`)."""
        try:
            if threading.get_ident() == self._engine_thread:
                return job()
            return self._executor.submit(job).result()
        except StoreWriteError as exc:
            raise self._storage_failed(exc) from exc

    def _storage_failed(self, exc: StoreWriteError) -> RefusedAction:
        """A write to the study failed (a full disk): nothing of it was stored and the engine's
        state is still the stored one, but the rig and the engine may now disagree, so the session
        stops here — every further action is refused with the reason, and the worker stops — until
        it is resumed (which records a trial left running as aborted)."""
        if self._store_fault is None:
            self._store_fault = (f"{exc} (run-session --resume, or restart serve and open the "
                                 "participant)")
            self._failed = self._failed or self._store_fault
            log.error("the session stops: %s", self._store_fault)
            self._changed(self._store_fault)
        return RefusedAction(self._store_fault)

    def _record(self, what: str, record: Callable[[SessionEngine], None]) -> None:
        """``record`` in the open session, if one is open (on the engine thread)."""
        if self._engine is not None:
            try:
                record(self._engine)
            except (RefusedAction, StoreError) as exc:
                log.error("%s was not recorded: %s", what, exc)

    def _end_session(self) -> str:
        engine = self._require_engine()
        if engine.state.running_trial is not None or (self._rig and self._rig.running is not None):
            raise RefusedAction("ending the session refused while a trial runs: abort it first")
        if engine.state.step is not Step.DONE and not engine.state.paused:
            engine.pause(END_REASON)
        code = engine.participant.code
        if self._rig is not None:
            self._rig.close()
            self._rig, self._devices = None, None
        self._close_engine()
        self._plan, self._participant, self._theta_star = None, None, []
        self._learner_fault, self._failed, self._failed_in_a_row = None, None, 0
        self._overview = None
        self._auto = False  # the next participant is not rated by the simulated one unless asked
        return code

    def _open(self, code: str, scenario: Scenario | None, seed: int | None, confirm: bool,
              confirm_seed: bool) -> None:
        if self._engine is not None:
            raise RefusedAction(f"participant {self._engine.participant.code!r} is open: end "
                                "that session first (End session)")
        exists = ParticipantStore.exists(self.study, code)
        if not exists:
            refuse_case_twin(self.study, code)
        if not exists and scenario is None:
            raise RefusedAction(f"participant {code!r} has no session yet: choose a scenario "
                                "to create one")
        lab = self.lab.model_dump(mode="json")
        with contextlib.ExitStack() as creation:
            if exists:
                config, recorded, _ = recorded_session(self.study, code)
                changed = recorded if recorded != self._rig_identity() else None
                if changed is not None and not confirm:
                    raise RefusedAction(
                        f"participant {code!r} was recorded on a different rig "
                        f"({describe_change(recorded, self._rig_identity())}); to continue on this "
                        "one, confirm the rig change (dashboard: 'Confirm a rig change'; "
                        "run-session: --accept-rig-change)")
            else:
                # the plan is validated before anything is written (with the seed asked for, or
                # 0); the seed is checked and the session created in one step for the study folder
                config, changed = self.lab.study_config(scenario, seed or 0), None
                creation.enter_context(writer_lock.creating_participant(self.study))
                config = config.model_copy(
                    update={"seed": choose_seed(self.study, seed, confirm_seed)})
            self._lock = writer_lock.reserve(participant_path(self.study, code))
            try:
                self._open_rig(config)
                if exists:
                    engine = SessionEngine.resume(self.study, code)
                else:
                    engine = SessionEngine.create(self.study, code, config)
            except BaseException:
                self._release_lock()
                raise
        used = {**self._trial_config(config).model_dump(mode="json"),
                **{table: lab[table] for table in ("protocol", "learner")}}
        engine.record_devices(used, self._devices.model_dump(mode="json"), self._rig_identity(),
                              changed_from=changed)
        engine.switch_simulated_participant(self._auto)
        if self._blind is not None:
            engine.set_blinding(self._blind)
        if engine.pause_reason() == END_REASON:  # opening it again is the experimenter's resume
            engine.resume_session(REOPEN_REASON)
        self._engine = engine
        self._open_outlets(engine)
        self._participant = SimulatedParticipant(engine.config.seed)
        if engine.state.step is not Step.DONE:
            warm_up()  # the learner's imports run while the experimenter pairs the tablet
        self._theta_star_key = -1
        self._overview = None
        log.info("session %s open at step %s", code, engine.state.step)

    def _open_outlets(self, engine: SessionEngine) -> None:
        """The session's LSL outlets, when the lab has them on and trials run on the wall clock
        (simulated time has no LSL time)."""
        if not (self.lab.record.lsl_outlets and self.realtime):
            return
        participant = engine.participant
        try:
            self._outlets = StudyOutlets(self.lab.record, participant.code, participant.created_at,
                                         self._devices.rate_hz,
                                         lambda: None if self._rig is None else self._rig.stream)
        except RuntimeError as exc:  # liblsl could not open them; the session itself is not at risk
            log.error("the study's LSL outlets could not open (%s): the session runs without them", exc)
            return
        engine.listeners.append(self._outlets.on_event)

    def _rig_identity(self) -> dict:
        """The rig tables a resume compares (a rehearsal's per-run addresses left out)."""
        rig = rig_of(self.lab.model_dump(mode="json"))
        return rig if self.rehearsal is None else rehearsal_rig(rig)

    def _trial_config(self, session: StudyConfig) -> ControllerConfig:
        """The session's controller configuration on this lab's rig."""
        rig = {table: getattr(self.lab, table) for table in RIG_TABLES}
        return session.controller.model_copy(update=rig)

    def _open_rig(self, session: StudyConfig) -> None:
        """Start a rig process for the session (the previous one, if any, is closed)."""
        if self._rig is not None:
            self._rig.close()
            self._rig = None
        spec = RigSpec(config=self._trial_config(session), scenario=session.scenario,
                       realtime=self.realtime, realtime_priority=self.realtime_priority)
        try:
            self._rig = RigClient(spec, self._on_report)
        except (RobotIOError, OSError) as exc:
            self._rig_fault = explain(exc)
            raise RefusedAction(f"the rig could not start: {explain(exc)}") from exc
        self._devices, self._rig_fault = self._rig.devices, None
        self._timing, self._hand_link = None, None

    def _start_trial(self) -> TrialPlan:
        engine = self._require_engine()
        if self._stop != "armed":
            raise RefusedAction("Start refused: the arm was stopped (STOP ARM); make sure the scene "
                                "is safe, then press Re-arm")
        blocker = self._pairing.status().blocker() if self.tablet_required else None
        if blocker is not None:
            raise RefusedAction(f"Start refused: {blocker}")
        if self._rig is None or not self._rig.alive:
            self._open_rig(engine.config)  # a fresh rig process after one died
        elif self._rig_fault is not None:
            raise RefusedAction(f"Start refused: the arm has a fault ({self._rig_fault}); inspect "
                                "it, then press Recover arm")
        plan = engine.start_trial()
        auto = self._auto or self.auto_experimenter
        self._plan, self._abort_reason, self._ready_wait = plan, None, None
        self._abort_actor = Actor.SYSTEM
        try:
            self._rig.run_trial(RunTrial(trial_index=plan.trial.trial_index, theta=plan.theta,
                                         hand_seed=plan.trial.hand_seed, auto_loaded=auto,
                                         auto_go=auto))
        except RobotIOError as exc:
            engine.end_trial(plan.trial.trial_index, None, f"could not start: {exc}", Actor.SYSTEM)
            raise RefusedAction(f"the trial could not start: {exc}") from exc
        return plan

    def _end_trial(self, trial_index: int, record: TrialRecord, reason: str | None) -> Trial | None:
        """Record the trial's end, unless it was already recorded (by whom: the experimenter if
        they aborted or stopped it, else the system)."""
        engine = self._engine
        if engine is None or engine.state.running_trial != trial_index:
            return None
        actor = self._abort_actor if reason is not None else Actor.SYSTEM
        return engine.end_trial(trial_index, record, reason, actor)

    def _close_engine(self) -> None:
        if self._outlets is not None:
            self._outlets.close()
            self._outlets = None
        if self._engine is not None:
            self._engine.close()
            self._engine = None
        self._release_lock()

    def _release_lock(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def _require_engine(self) -> SessionEngine:
        if self._store_fault is not None:
            raise RefusedAction(self._store_fault)
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

    def _require_waiting(self, what: Waiting) -> RigClient:
        if self._view.waiting_for != what or self._rig is None:
            raise RefusedAction(f"refused: the trial is not waiting for '{what}'")
        return self._rig

    def _status(self) -> Status:
        """The view's fields that do not come from the engine (read without its thread)."""
        rig = RigStatus(devices=self._devices, fault=self._rig_fault, timing=self._timing,
                        hand_link=self._hand_link, ready_wait=self._ready_wait, stop=self._stop)
        return Status(rig=rig, realtime=self.realtime, rehearsal=self.rehearsal is not None,
                      refusing_object=self._refusing_object, preparing=self._preparing,
                      learner_fault=self._learner_fault, failed=self._failed,
                      tablet=None if self._pairing is None else self._pairing.status(),
                      tablet_required=self.tablet_required, messages=list(self._messages),
                      auto=self._auto)

    def _make_view(self) -> RunnerView:
        engine = self._engine
        if self._overview is None:
            self._overview = (self._study_overview.lines() if engine is None else
                              self._study_overview.lines(engine.store, engine.participant.code))
        session = None
        if engine is not None:
            state = engine.state
            if self._theta_star_key != len(state.planned):  # a new θ means a new learner snapshot
                self._theta_star_key = len(state.planned)
                self._theta_star = [
                    ThetaStar(after_interaction=r.after_interaction, a=r.theta_star_a,
                              delta=r.theta_star_delta, k=r.theta_star_k)
                    for r in engine.store.rows("learner_snapshots") if r.theta_star_a is not None]
            session = SessionFacts(
                code=engine.participant.code, scenario=engine.config.scenario,
                seed=engine.config.seed, state=state.model_copy(deep=True),
                interactions=engine.config.interactions,
                trials=engine.store.rows("trials", order_by="trial_index"),
                theta_star=self._theta_star, posterior=engine.posterior_slices)
        return build_view(next(self._made), self._status(), self._overview, session,
                          self.auto_experimenter)

    # -- internals: the rig's reports (on its reader thread) --------------------------------------
    def _on_report(self, report: Report | RigDied) -> None:
        if isinstance(report, StageReached):
            self._on_stage(report)
        elif isinstance(report, ReadyWaiting):
            self._ready_wait = report.why
            self._changed(None)
        elif isinstance(report, RigTiming):
            first = self._timing is None or self._timing.trial_index != report.trial_index
            self._timing = report
            if first:  # the whole of it on stderr (headless too); the dashboard shows it by the devices
                log.warning("%s", report.describe())
            self._changed(f"trial {report.trial_index}: the rig's timing runs late (see Devices)"
                          if first else None)
        elif isinstance(report, HandLink):
            self._hand_link = report.notice
            self._changed_now(None)
        elif isinstance(report, TrialDone):
            if self._timing is not None and self._timing.trial_index != report.trial_index:
                self._timing = None  # this trial ran on time
            self._flush_outlets()
            self._finish(report.trial_index, TrialRecord(report.summary, self._rig.stream.columns()))
        elif isinstance(report, RigDied):
            self._rig_fault = report.reason
            self._flush_outlets()
            if report.trial_index is not None:
                record = not_started(self._rig.spec.config, self.realtime, Outcome.ERROR,
                                     report.reason)
                self._finish(report.trial_index, TrialRecord(record.summary,
                                                             self._rig.stream.columns()),
                             self._abort_reason or report.reason)
            else:
                if self._stop == "stopping":
                    self._stop = "stopped"
                self._changed(report.reason)

    def _flush_outlets(self) -> None:
        """The robot stream gets the rest of the trial's rows before anything else happens."""
        outlets = self._outlets
        if outlets is not None:
            outlets.feed.flush()

    def _on_stage(self, report: StageReached) -> None:
        plan = self._plan
        outlets = self._outlets
        if report.stage is Stage.GO and outlets is not None:
            outlets.feed.go(report.trial_index, report.monotonic)
        if report.stage is Stage.GO and self.rehearsal is not None and plan is not None:
            self.rehearsal.play(self._engine.config.scenario, plan.trial.hand_seed,
                                report.monotonic)
        if report.stage is Stage.READY:
            self._ready_wait = None
        try:
            at = utc_of_monotonic(report.monotonic)
            self._call(lambda: self._require_engine().record_stage(
                report.trial_index, report.stage, report.t,
                at=at.isoformat(timespec="microseconds")))
        except (RefusedAction, StoreError) as exc:
            log.warning("stage %s not recorded: %s", report.stage.value, exc)
        self._changed(None)

    def _finish(self, trial_index: int, record: TrialRecord, reason: str | None = None) -> None:
        if self.rehearsal is not None:
            self.rehearsal.rest()
        summary = record.summary
        # A fault of the arm or of the gripper locks Start until the experimenter has inspected it:
        # after a gripper fault mid-hold the arm holds the object out where it stopped, and the next
        # Start's prepare would move it back to R with the object.
        if summary.outcome in (Outcome.ARM_FAULT, Outcome.GRIPPER_FAULT) or summary.retract_fault:
            self._rig_fault = summary.retract_fault or summary.reason
        try:
            ended = self._call(lambda: self._end_trial(trial_index, record,
                                                       reason or self._abort_reason))
        except RefusedAction as exc:  # not stored (the session stopped): resuming repeats it
            log.error("trial %d's end not recorded: %s", trial_index, exc)
            return
        if self._stop == "stopping":
            self._stop = "stopped"  # the arm has stopped: the trial is over
        if ended is None:
            self._changed(None)
            return
        self._overview = None
        self._failed_in_a_row = 0 if ended.outcome.value == "completed" else self._failed_in_a_row + 1
        self._changed(f"trial {ended.trial_index} {ended.outcome.value}"
                      + (f": {ended.reason}" if ended.reason else ""))

    # -- internals: other threads -----------------------------------------------------------------
    def _halt(self, reason: str) -> None:
        """The experimenter's Abort or Stop."""
        rig = self._rig
        if rig is None:
            return
        if rig.running is not None and self._abort_reason is None:
            self._abort_reason, self._abort_actor = reason, Actor.EXPERIMENTER
        rig.stop(reason)

    def _changed(self, message: str | None) -> None:
        if message is not None:
            self._messages.append(f"{time.strftime('%H:%M:%S')} {message}")
            log.info("%s", message)
        self._publish()
        self._wake.set()

    def _changed_now(self, message: str | None) -> None:
        """Like :meth:`_changed` for device news (stop, tablet): published at once, without
        waiting for the engine thread (which may be busy with the learner for a while)."""
        if message is not None:
            self._messages.append(f"{time.strftime('%H:%M:%S')} {message}")
            log.info("%s", message)
        if not self._closing:
            with self._showing:  # the shown view's engine state, with the devices' news
                self._notify(with_news(self._view, self._status()))
        self._wake.set()

    def _publish(self) -> None:
        if self._closing:
            return
        view = self._call(self._make_view)
        with self._showing:
            if view.version > self._view.version:  # else a view made later is already shown
                self._notify(with_news(view, self._status()))

    def _notify(self, view: RunnerView) -> None:
        self._view = view
        for listener in list(self._listeners):
            try:
                listener(view)
            except Exception:
                log.exception("a screen failed to render")

    def _work(self) -> None:
        """The background worker: plans the next θ, lets the simulated participant act and, headless,
        the simulated experimenter start trials."""
        while not self._closing:
            self._wake.wait()
            self._wake.clear()
            while not self._closing and self._next_job():
                pass

    def _next_job(self) -> bool:
        view = self._view
        if view.state is None or self._failed is not None:
            return False
        step = view.step
        if step is Step.PLAN:
            self._plan_next()
            return False
        if self._auto and step in PARTICIPANT_STEPS:
            if self.realtime:
                time.sleep(AUTO_DELAY_S)
            try:
                self._call(lambda: self._auto_step(step))
            except RefusedAction as exc:
                log.warning("the simulated participant's answer was refused: %s", exc)
                return False
            self._changed("the simulated participant rated")
            return True
        if self.auto_experimenter and step is Step.READY and not view.state.paused:
            return self._auto_start()
        return False

    def _auto_start(self) -> bool:
        if self._failed_in_a_row >= MAX_FAILED_TRIALS:
            self._failed = (f"{MAX_FAILED_TRIALS} trials in a row did not complete; the last: "
                            f"{self._view.trials[-1].reason if self._view.trials else '?'}")
            self._changed(self._failed)
            return False
        if self._rig_fault is not None and self._rig is not None and self._rig.alive:
            try:
                self.recover_arm(inspected=False)  # never a safety stop: that needs a person
            except RefusedAction as exc:
                self._failed = f"the arm needs a person: {exc}"
                self._changed(self._failed)
                return False
        try:
            self.start_trial()
        except RefusedAction as exc:
            self._failed_in_a_row += 1
            self._changed(str(exc))
            return self._failed_in_a_row < MAX_FAILED_TRIALS
        return False

    def _auto_step(self, step: Step) -> None:
        if self._auto and self._engine is not None and self._engine.state.step is step:
            rate_once(self._engine, self._participant)

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
