"""The running session behind both screens and the headless command (docs/controller.md, the rig process).

One :class:`SessionRunner` owns the participant's :class:`SessionEngine` and, through its
:class:`~app.session.supervisor.TrialSupervisor`, the rig process that runs each trial's handover
cycle on the configured devices; ``handover serve`` renders it on the tablet and the dashboard,
``handover run-session`` drives it headless, so both run the same trials on the same devices. A
background worker (:class:`~app.session.autopilot.Autopilot`) asks the learner for the next θ and,
when switched on, lets the simulated participant rate (and, headless, the simulated experimenter
start each trial). Every change is published as a :class:`RunnerView` (:mod:`app.session.view`) — a
consistent copy of the engine's state plus device status — to the subscribed screens, which render
nothing else.

The engine (and its SQLite connection, which belongs to one thread) is only touched on one engine
thread, one call at a time; so is the rest of this class's session state. :meth:`SessionRunner.stop`
never waits for it: it goes straight to the rig (and past it, to the controller, if the rig does
not answer), so Stop reaches the arm whatever else is going on. Which thread owns what:
docs/architecture.md, "Threads and who owns what".
"""

from __future__ import annotations

import itertools
import logging
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np

from app.learning.errors import LearningError
from app.protocol.engine import TrialPlan
from app.protocol.entries import Entry, EntryNotUsed, enter
from app.protocol.errors import RefusedAction
from app.protocol.state import Step
from app.protocol.study_config import StudyConfig
from app.session import faults
from app.session.access import TABLET_BROWSER_FILE, KnownBrowsers
from app.session.autopilot import Autopilot
from app.session.config import LabConfig
from app.session.engine_side import END_REASON, REOPEN_REASON, EngineSide
from app.session.engine_thread import EngineThread, SessionClosed
from app.session.faults import StagedFault
from app.session.opening import rig_identity, trial_config
from app.session.pairing import TabletPairing
from app.session.publisher import Listener, Publisher
from app.session.rehearsal import Rehearsal
from app.session.supervisor import Recording, TrialSupervisor
from app.session.view import RunnerView, Status, build_view
from robot_io.clock import utc_of_monotonic
from robot_io.config import SceneConfig
from robot_io.control.loop import TrialRecord
from robot_io.control.stages import current
from robot_io.errors import RobotIOError
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.client import RigClient
from robot_io.rig.messages import DeviceReport, StageReached
from robot_io.rig.stream import SampleStream
from session_store.errors import StoreError, StoreWriteError
from session_store.models import Trial
from session_store.store import participant_codes
from session_store.vocabulary import Actor, Hint, Rater

__all__ = ["CLOSE_REASON", "END_REASON", "PLAN_TIMEOUT_S", "REOPEN_REASON", "RunnerView",
           "SessionRunner"]

log = logging.getLogger(__name__)

#: How long the planner waits for the learner before it falls back to a flagged Sobol point [s].
PLAN_TIMEOUT_S = 60.0
#: The reason recorded with a trial still running when the session closes (serve's Ctrl-C).
CLOSE_REASON = "session closed"

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
        self.auto_experimenter = auto_experimenter
        self._engine = EngineThread()  # created here, closed last by close()
        self._side = EngineSide(study, self.lab, realtime=realtime)  # on the engine thread only
        self._made = itertools.count(1)  # views, numbered as they are made (on the engine thread)
        # the experimenter's switches, from any thread under the switches' lock (one read or write)
        self._switches = threading.Lock()
        self._auto = False
        self._blind: bool | None = None  # the dashboard's validation blinding; None: no dashboard
        self._refusing_object = False
        self._pairing: TabletPairing | None = None  # set once, by attach_tablet before serving
        self._closing = threading.Event()
        self._publisher = Publisher(lambda: self._call(self._make_view), self._status,
                                    self._engine.forbid)
        self._supervisor = TrialSupervisor(
            Recording(stage=self._record_stage, trial_end=self._record_trial_end,
                      outlets=lambda: self._side.outlets, changed=self._publisher.changed,
                      news=self._publisher.news),
            realtime=realtime, realtime_priority=realtime_priority, rehearsal=rehearsal)
        # a change (a new view, waits for the engine thread) and device news (does not)
        self._changed, self._news = self._publisher.changed, self._publisher.news
        self._autopilot = Autopilot(self)

    # -- reading --------------------------------------------------------------------------------
    @property
    def view(self) -> RunnerView:
        """The latest published view (never blocks)."""
        return self._publisher.view

    def subscribe(self, listener: Listener) -> None:
        self._publisher.subscribe(listener)

    def live(self, stride: int = 1) -> tuple[TrialPlan | None, dict[str, np.ndarray] | None]:
        """The running (or last) trial and its rows so far with the arm's links
        (:func:`~app.session.drawing.with_links`), for live displays (never blocks)."""
        return self._supervisor.live(stride)

    def scene_config(self) -> SceneConfig:
        """The geometry of the open session (the lab's before one is open)."""
        engine = self._side.engine
        return (self.lab if engine is None else engine.config.controller).scene

    def codes(self) -> list[str]:
        """The participants of the study folder."""
        return participant_codes(self.study) if self.study.exists() else []

    @property
    def rig(self) -> RigClient | None:
        return self._supervisor.rig

    def trial_rows(self, trial_index: int) -> dict[str, np.ndarray]:
        """A stored trial of the open participant, as the live view's columns with the arm's links
        (for a replay); refused while a trial runs."""
        return self._call(lambda: self._side.replay_rows(trial_index))

    # -- the tablet (one per session) -------------------------------------------------------------
    def attach_tablet(self) -> TabletPairing:
        """The tablet screen's pairing: from now on a trial starts only with exactly one paired
        tablet open (the simulated participant on a simulated rig excepted)."""
        self._pairing = TabletPairing(known=KnownBrowsers(self.study, TABLET_BROWSER_FILE))
        self._changed()
        return self._pairing

    def _tablet(self) -> TabletPairing:
        """The pairing of the tablet page that calls (a page is served only once attached)."""
        assert self._pairing is not None, "attach_tablet comes before serve serves a page"
        return self._pairing

    def tablet_connected(self, page: int, address: str, browser: str | None = None) -> None:
        """A page opened on the tablet port from ``address``, in ``browser`` (its id, if known)."""
        again = self._tablet().connected(page, address, browser)
        self._news("the tablet is paired again (the browser paired before)" if again else None)

    def tablet_closed(self, page: int) -> None:
        self._tablet().closed(page)
        self._news(None)

    def pair_tablet(self, page: int, code: str) -> str | None:
        """The code typed on a tablet page: None if it is now the study's tablet, else why not."""
        pairing = self._tablet()
        before = pairing.status()
        refusal = pairing.pair(page, code)
        after = pairing.status()
        if refusal is None and before.address not in (None, after.address):
            message = f"the tablet was taken over: from {before.address} to {after.address}"
        elif refusal is None:
            message = "the tablet is paired"
        elif after.code != before.code:
            message = f"{after.wrong_codes} wrong pairing codes: the code was replaced"
        else:
            message = None
        self._news(message)
        return refusal

    @property
    def tablet_required(self) -> bool:
        """Whether a trial needs the paired tablet: always with a tablet screen, except when the
        simulated participant rates on a simulated rig (mock arm or rehearsal)."""
        simulated_rig = self.rehearsal is not None or self.lab.arm.simulated
        return self._pairing is not None and not (self._auto_on() and simulated_rig)

    def _auto_on(self) -> bool:
        """Whether the simulated participant is on."""
        with self._switches:
            return self._auto

    # -- the experimenter's actions ---------------------------------------------------------------
    def open(self, code: str, scenario: Scenario | None = None, seed: int | None = None,
             confirm_rig_change: bool = False, confirm_seed_reuse: bool = False) -> None:
        """Resume ``code``'s session, or create it (with ``scenario``) if it has none
        (:func:`~app.session.opening.open_session`: the writer lock, the seed, the rig change)."""
        self._call(lambda: self._open(code, scenario, seed, confirm_rig_change, confirm_seed_reuse))
        self._changed(f"participant {code} open on {self._rig_detail()}")

    def start_trial(self) -> Trial:
        """Start the next trial; the trial started."""
        plan = self._call(self._start_trial)
        self._changed(f"trial {plan.trial.trial_index} started (interaction "
                      f"{plan.trial.interaction}, attempt {plan.trial.attempt})")
        return plan.trial

    def confirm(self, stage: str) -> None:
        """The experimenter gives the confirmation the running trial's ``stage`` waits for (its
        gate: Object loaded in prepare, Go in ready — the tablet's cue and the robot's start)."""
        rig = self._supervisor.rig
        gate = current().gate(stage)
        if gate is None or self.view.waiting_for != stage or rig is None:
            raise RefusedAction(f"refused: the trial is not waiting in '{stage}'")
        rig.confirm(stage)
        self._changed(gate.button)

    def recover_arm(self, inspected: bool = True) -> None:
        """Clear the arm's fault once its cause is inspected (moves nothing); a UR's protective stop
        is unlocked no sooner than 5 s after it happened. When the rig process has ended (its
        fault), a fresh one is opened: it connects to the devices and moves nothing."""
        if not self._supervisor.alive:
            self._call(lambda: self._open_rig(self._side.require().config))
            self._changed(f"a fresh rig process is open on {self._rig_detail()}")
            return
        self._changed(self._supervisor.recover(inspected))

    def abort_trial(self) -> None:
        """End the running trial now; it is recorded as aborted and will be repeated."""
        self._supervisor.abort()

    def stop(self) -> None:
        """Stop the arm, whatever else is going on (never waits for the engine). A running trial
        is aborted. Start stays locked until :meth:`rearm`."""
        self._news(self._supervisor.stop())

    def rearm(self) -> None:
        """The experimenter confirms the scene is safe after a stop: trials may start again."""
        self._supervisor.rearm()
        self._news("re-armed: the experimenter confirmed the scene is safe")

    def end_session(self) -> None:
        """End the open participant's session (paused if it is not complete, so it resumes where
        it was) and close its rig, so that another participant can be opened. The simulated
        participant is off for the next one unless asked again."""
        code = self._call(self._end_session)
        with self._switches:
            self._auto = False
        self._changed(f"session of {code} ended")

    def pause(self) -> None:
        self._call(lambda: self._side.require().pause("paused by the experimenter"))
        self._changed("session paused")

    def resume(self) -> None:
        self._call(lambda: self._side.require().resume_session())
        self._changed("session resumed")

    def set_auto(self, on: bool) -> None:
        """Switch the simulated participant on or off; recorded in the open session (and in the
        next one opened), so that every rating's origin is known. Published at once; the record is
        written in order on the engine thread, without waiting for it (a screen's refresh may call
        this)."""
        with self._switches:
            self._auto = on
        self._post(lambda: self._side.record("the simulated participant's switch",
                                             lambda engine: engine.switch_simulated_participant(on)))
        self._news(f"simulated participant {'on' if on else 'off'}")

    def set_blinding(self, blind: bool) -> None:
        """The dashboard hides the θ and origin of validation trials (``blind``, the paper's blind
        validation) or shows them (pilots, debugging); recorded in the open session and in every
        one opened later, so each session says how its validation was run."""
        with self._switches:
            self._blind = blind
        self._post(lambda: self._side.record("the validation's blinding",
                                             lambda engine: engine.set_blinding(blind)))

    def stage_fault(self, fault: StagedFault) -> None:
        """A rehearsal stages ``fault`` now (see :mod:`app.session.faults`); refused on the rig."""
        self._news(faults.stage(fault, self.rehearsal, self._supervisor.rig))

    def refuse_object(self, refuse: bool) -> None:
        """A rehearsal's simulated participant stops (or starts again) taking the object."""
        message = faults.refuse_object(self.rehearsal, refuse)
        with self._switches:
            self._refusing_object = refuse
        self._news(message)

    # -- the participant's actions (each names the interaction its screen showed) -----------------
    # ``by``: the participant on the tablet, or the experimenter entering it for them (dashboard);
    # an answer after another for the same prompt is recorded as not used (app.protocol.entries)
    def place(self, interaction: int, position: float | None = None,
              equal_to: int | None = None, by: Rater = Rater.PARTICIPANT) -> None:
        self._enter(Entry(kind="placement", interaction=interaction, position=position,
                          equal_to=equal_to, by=by))

    def hint(self, interaction: int, hint: Hint | None, by: Rater = Rater.PARTICIPANT) -> None:
        """A coactive hint about ``interaction`` (None: nothing to change)."""
        self._enter(Entry(kind="hint", interaction=interaction, hint=hint, by=by))

    def rate(self, interaction: int, rating: str, by: Rater = Rater.PARTICIPANT) -> None:
        self._enter(Entry(kind="rating", interaction=interaction, rating=rating, by=by))

    def answer(self, question: str, value: str, by: Rater = Rater.PARTICIPANT) -> None:
        self._enter(Entry(kind="answer", question=question, value=value, by=by))

    def _enter(self, entry: Entry) -> None:
        """Take the participant's answer; one that came after another's for the same prompt is
        news for the experimenter (and refused, with what counts instead)."""
        try:
            self._call(lambda: enter(self._side.require(), entry))
        except EntryNotUsed as exc:
            self._changed(f"⚠ {exc}")
            raise
        self._changed(None)

    # -- the background worker's actions (app.session.autopilot) ----------------------------------
    def plan_next(self) -> None:
        """The learner plans the next θ (the view says "fitting the next θ" meanwhile, and then
        whether the learner was late or failed, or that learning stopped early)."""
        self._call(lambda: self._side.planning(True, self._side.learner()[1]))
        self._changed()
        fault = news = None
        try:
            planned, news = self._call(lambda: self._side.plan(PLAN_TIMEOUT_S))
            fault = "the learner was late: a Sobol point was used (fallback)" if planned.fallback else None
        except (LearningError, RefusedAction, StoreError) as exc:
            # the learner's failure with its stack; a stopped session or a refused write (a full
            # disk: already said by _call) in words only, as the session's terminal says them
            log.error("planning the next θ failed: %s", exc, exc_info=isinstance(exc, LearningError))
            fault = f"{type(exc).__name__}: {exc}"
        finally:
            self._call(lambda: self._side.planning(False, fault))
            self._changed(news)

    def simulated_turn(self, step: Step) -> None:
        """The simulated participant places, rates or answers, if it is on and the session still
        waits for ``step``."""
        self._call(lambda: self._side.simulated_turn(step, self._auto_on()))
        self._changed("the simulated participant rated")

    def note(self, message: str) -> None:
        """An event for the dashboard's list and the log."""
        self._changed(message)

    def give_up(self, reason: str) -> None:
        """The simulated experimenter gives up: the session stops here with ``reason``."""
        self._call(lambda: self._side.fail(reason))
        self._changed(reason)

    # -- shutdown ---------------------------------------------------------------------------------
    def close(self, reason: str = CLOSE_REASON) -> None:
        """Stop the arm first, then close the rig, the engine and its store, and the rehearsal; a
        running trial is recorded aborted with ``reason``. Closing twice does nothing more. Not
        from the engine thread nor from a subscriber (it waits for both).

        The order is each shared object's users before its releaser (docs/architecture.md,
        "Shared objects and their lifetimes"): the worker is told to stop and the screens get no
        more views; the supervisor stops the arm and closes the rig, waiting until its last reports
        (a stopped trial's end) are recorded on the engine thread; the engine thread closes the
        outlets, the store and the writer lock, and then ends, refusing every later job
        (:class:`~app.session.engine_thread.SessionClosed`, which the worker takes as its end);
        the worker is joined; the rehearsal's stand-ins go last, after the rig that spoke to them."""
        self._engine.forbid("closing the session")
        if self._closing.is_set():
            return
        self._closing.set()
        self._autopilot.stop()
        self._publisher.close()
        self._supervisor.close(reason)
        try:
            self._call(self._side.close)
        finally:
            self._engine.close()
            self._autopilot.join()
            if self.rehearsal is not None:
                self.rehearsal.close()

    # -- internals: on the engine thread ----------------------------------------------------------
    def _call(self, job: Callable[[], T]) -> T:
        """Run ``job`` on the engine thread and return its result (or raise its exception; a
        failed write to the study stops the session: :meth:`EngineSide.storage_failed`, published
        here the first time)."""
        if self._engine.on_it():
            return job()
        try:
            return self._engine.call(lambda: self._guarded(job))
        except _SessionStopped as stopped:
            if stopped.first:
                log.error("the session stops: %s", stopped.reason)
                self._changed(stopped.reason)
            raise RefusedAction(stopped.reason) from stopped.__cause__

    def _post(self, job: Callable[[], object]) -> None:
        """Queue ``job`` on the engine thread without waiting (nothing once the session closed)."""
        try:
            self._engine.post(job)
        except SessionClosed:
            log.info("not recorded: the session is closed")

    def _guarded(self, job: Callable[[], T]) -> T:
        try:
            return job()
        except StoreWriteError as exc:
            raise _SessionStopped(*self._side.storage_failed(exc)) from exc

    def _end_session(self) -> str:
        rig = self._supervisor.rig
        return self._side.end(rig is not None and rig.running is not None,
                              self._supervisor.close_rig)

    def _open(self, code: str, scenario: Scenario | None, seed: int | None, confirm: bool,
              confirm_seed: bool) -> None:
        with self._switches:
            auto, blind = self._auto, self._blind
        identity = rig_identity(self.lab, self.rehearsal is not None)
        self._side.open(code, scenario, seed, identity=identity, confirm_rig_change=confirm,
                        confirm_seed_reuse=confirm_seed, open_rig=self._open_rig, auto=auto,
                        blind=blind, stream=self._stream, notify=self._news)

    def _stream(self) -> SampleStream | None:
        """The open rig's samples (for the study's LSL outlets)."""
        rig = self._supervisor.rig
        return None if rig is None else rig.stream

    def _open_rig(self, session: StudyConfig) -> DeviceReport:
        """Start a rig process for the session (the previous one, if any, is closed); its devices."""
        self._supervisor.open(trial_config(self.lab, session), session.scenario)
        return self._devices()

    def _devices(self) -> DeviceReport:
        """The devices of the rig opened just before."""
        devices = self._supervisor.status().devices
        assert devices is not None, "a rig was opened just before"
        return devices

    def _rig_detail(self) -> str:
        """The arm of the rig opened just before, for the session's log."""
        return self._devices().arm_detail

    def _start_trial(self) -> TrialPlan:
        engine = self._side.require()
        self._supervisor.refuse_unless_armed()
        blocker = self._tablet().status().blocker() if self.tablet_required else None
        if blocker is not None:
            raise RefusedAction(f"Start refused: {blocker}")
        self._supervisor.ready_rig(trial_config(self.lab, engine.config), engine.config.scenario)
        plan = engine.start_trial()
        try:
            self._supervisor.run(plan, self._auto_on() or self.auto_experimenter)
        except (RobotIOError, RefusedAction) as exc:
            engine.end_trial(plan.trial.trial_index, None, f"could not start: {exc}", Actor.SYSTEM)
            raise RefusedAction(f"the trial could not start: {exc}") from exc
        return plan

    def _record_stage(self, report: StageReached) -> None:
        """A stage the rig reached, recorded with its time (from the rig's reader thread)."""
        try:
            at = utc_of_monotonic(report.monotonic).isoformat(timespec="microseconds")
            self._call(lambda: self._side.record_stage(report, at))
        except (RefusedAction, StoreError) as exc:
            log.warning("stage %s not recorded: %s", report.stage, exc)
        self._changed()

    def _record_trial_end(self, trial_index: int, record: TrialRecord, reason: str | None,
                          actor: Actor) -> Trial | None:
        """Record the trial's end, unless it was already recorded (from the rig's reader thread)."""
        return self._call(lambda: self._side.trial_end(trial_index, record, reason, actor))

    def _make_view(self) -> RunnerView:
        """A new view, numbered (on the engine thread)."""
        return build_view(next(self._made), self._status(), self._side.overview(),
                          self._side.facts(), self.auto_experimenter, self._side.plan_status())

    def _status(self) -> Status:
        """The view's fields that do not come from the engine (read without its thread)."""
        preparing, learner_fault = self._side.learner()
        with self._switches:
            auto, refusing = self._auto, self._refusing_object
        return Status(rig=self._supervisor.status(), realtime=self.realtime,
                      rehearsal=self.rehearsal is not None, refusing_object=refusing,
                      preparing=preparing, learner_fault=learner_fault, failed=self._side.failed,
                      tablet=None if self._pairing is None else self._pairing.status(),
                      tablet_required=self.tablet_required, messages=self._publisher.messages(),
                      auto=auto, recording=self._side.recording_status())


class _SessionStopped(Exception):
    """Raised on the engine thread when a write to the study failed; ``first``: the first failure,
    which the calling thread publishes."""

    def __init__(self, reason: str, first: bool) -> None:
        super().__init__(reason)
        self.reason, self.first = reason, first
