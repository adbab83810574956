"""The session runner's state on its engine thread: the open participant's engine and store (with
the writer lock), its LSL outlets, the simulated participant, the learner's status, why the session
stopped, and what the view is read from.

Every method runs on the engine thread (the runner's single-worker executor), one call at a time:
the engine's SQLite connection belongs to that thread. Other threads only read
:meth:`EngineSide.learner`, :attr:`EngineSide.failed`, :attr:`EngineSide.engine` and
:attr:`EngineSide.outlets`, each a single reference replaced whole (docs/architecture.md,
"Threads and who owns what")."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from app.learning.worker import warm_up
from app.protocol.auto import rate_once
from app.protocol.design import Participant, PlanStatus
from app.protocol.engine import SessionEngine
from app.protocol.errors import RefusedAction
from app.protocol.learning_words import learning_line, recorded_stop, stop_headline
from app.protocol.safety_record import over_limits
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import PlannedTheta, Step
from app.protocol.study_config import StudyConfig
from app.session.config import LabConfig
from app.session.drawing import with_links
from app.session.lsl_outlets import StudyOutlets
from app.session.opening import open_session, trial_config
from app.session.overview import ParticipantSummary, StudyOverview
from app.session.rcs_client import RecorderError
from app.session.recording import RecordingStatus, SessionRecording
from app.session.view import SessionFacts, ThetaStar
from robot_io.control.loop import TrialRecord
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.messages import DeviceReport, StageReached
from robot_io.rig.silence import waited
from robot_io.rig.stream import SampleStream
from session_store import lock as writer_lock
from session_store.errors import StoreError, StoreWriteError
from session_store.models import Trial
from session_store.sample_rows import stored_rows
from session_store.vocabulary import Actor

log = logging.getLogger(__name__)

#: The reason recorded with the pause of a session the experimenter ended before it was complete,
#: and with its resume when the experimenter opens the participant again.
END_REASON = "ended by the experimenter"
REOPEN_REASON = "opened again by the experimenter"
#: How long closing a session waits for its learner warm-up to end [s]: once the forkserver serves,
#: a few milliseconds; only a close within seconds of the first open waits for its imports.
WARM_UP_WAIT_S = 10.0


def joined(thread: threading.Thread, seconds: float) -> bool:
    """``thread`` joined for at most ``seconds``: whether it has ended."""
    thread.join(seconds)
    return not thread.is_alive()


class EngineSide:
    """The open session on the engine thread (see the module's docstring)."""

    def __init__(self, study: Path, lab: LabConfig, *, realtime: bool) -> None:
        self.study, self.lab, self.realtime = study, lab, realtime
        self.engine: SessionEngine | None = None
        self.outlets: StudyOutlets | None = None  # the open session's LSL outlets ([record])
        self.recording: SessionRecording | None = None  # its XDF recording ([recording])
        self.failed: str | None = None  # storing failed, or the simulated experimenter gave up
        self._participant: SimulatedParticipant | None = None
        self._lock: writer_lock.WriterLock | None = None
        # the open session's learner warm-up (app.learning.worker.warm_up): its thread owns the
        # warm-up child and closes its two pipes to the forkserver; close() waits for it
        self._warming: threading.Thread | None = None
        self._learner: tuple[bool, str | None] = (False, None)  # preparing, the learner's fault
        self._store_fault: str | None = None  # a write to the study failed: the session stops
        self._theta_star: list[ThetaStar] = []
        self._learning: str | None = None  # the stopping signal in words, with the θ* above
        self._theta_star_key = -1
        self._overview: list[ParticipantSummary] | None = None  # None: to be read again
        self._study_overview = StudyOverview(study)

    # -- what other threads read ---------------------------------------------------------------
    def learner(self) -> tuple[bool, str | None]:
        """Whether the learner is fitting the next θ, and why its last θ is flagged (None: not)."""
        return self._learner

    # -- the session -------------------------------------------------------------------------------
    def require(self) -> SessionEngine:
        if self._store_fault is not None:
            raise RefusedAction(self._store_fault)
        if self.engine is None:
            raise RefusedAction("no participant is open: create or resume one first")
        return self.engine

    def open(self, code: str, scenario: Scenario | None, seed: int | None, *, identity: dict,
             confirm_rig_change: bool, confirm_seed_reuse: bool,
             open_rig: Callable[[StudyConfig], DeviceReport], auto: bool, blind: bool | None,
             stream: Callable[[], SampleStream | None],
             notify: Callable[[str], None] = log.warning) -> None:
        """Open ``code``'s session (:func:`~app.session.opening.open_session`) and record the
        devices it runs on, the simulated participant's switch (``auto``) and the validation's
        blinding (``blind``; None: no dashboard). ``stream``: the rig's samples, for the outlets;
        ``notify``: where the recording's warnings go (any thread)."""
        if self.engine is not None:
            raise RefusedAction(f"participant {self.engine.participant.code!r} is open: end "
                                "that session first (End session)")
        engine, self._lock, devices, changed = open_session(
            self.study, self.lab, identity, code, scenario, seed,
            confirm_rig_change=confirm_rig_change, confirm_seed_reuse=confirm_seed_reuse,
            open_rig=open_rig)
        lab = self.lab.model_dump(mode="json")
        used = {**trial_config(self.lab, engine.config).model_dump(mode="json"),
                **{table: lab[table] for table in ("protocol", "learner", "safety_record")}}
        engine.record_devices(used, devices.model_dump(mode="json"), identity,
                              changed_from=changed)
        engine.switch_simulated_participant(auto)
        if blind is not None:
            engine.set_blinding(blind)
        if engine.pause_reason() == END_REASON:  # opening it again is the experimenter's resume
            engine.resume_session(REOPEN_REASON)
        self.engine = engine
        self._open_outlets(engine, devices.rate_hz, stream)
        self._open_recording(engine, notify)
        self._participant = SimulatedParticipant(engine.config.seed)
        if engine.state.step is not Step.DONE:
            self._warming = warm_up()  # the learner's imports run while the tablet is paired
        self._theta_star_key = -1
        self._overview = None
        log.info("session %s open at step %s", code, engine.state.step)

    def _open_outlets(self, engine: SessionEngine, rate_hz: int,
                      stream: Callable[[], SampleStream | None]) -> None:
        """The session's LSL outlets, when the lab has them on and trials run on the wall clock
        (simulated time has no LSL time)."""
        if not (self.lab.record.lsl_outlets and self.realtime):
            return
        participant = engine.participant
        try:
            self.outlets = StudyOutlets(self.lab.record, participant.code, participant.created_at,
                                        rate_hz, stream)
        except RuntimeError as exc:  # liblsl could not open them; the session itself is not at risk
            log.error("the study's LSL outlets could not open (%s): the session runs without them", exc)
            return
        engine.listeners.append(self.outlets.on_event)

    def _open_recording(self, engine: SessionEngine, notify: Callable[[str], None]) -> None:
        """The session's recording, when the lab has one ([recording]): it starts before the first
        trial, or the session does not open (its file must appear); on simulated time there are
        no outlets and no LSL time to record."""
        if self.lab.recording.kind == "none":
            return
        if self.outlets is None:
            log.warning("[recording] kind = %r: nothing is recorded, the session has no LSL "
                        "outlets (simulated time, or they could not open)", self.lab.recording.kind)
            return
        try:
            self.recording = SessionRecording(self.lab.recording, self.study,
                                              engine.participant.code, self.outlets.source_ids,
                                              notify)
        except RecorderError as exc:
            self.close()
            raise RefusedAction(f"the session's recording did not start: {exc}") from exc
        engine.listeners.append(self.recording.on_event)

    def recording_status(self) -> RecordingStatus | None:
        """The recording now (any thread: a single reference, its status immutable)."""
        recording = self.recording
        return None if recording is None else recording.status()

    def end(self, trial_running: bool, close_rig: Callable[[], None]) -> str:
        """End the open session (paused if not complete) and close its rig; its code."""
        engine = self.require()
        if engine.state.running_trial is not None or trial_running:
            raise RefusedAction("ending the session refused while a trial runs: abort it first")
        if engine.state.step is not Step.DONE and not engine.state.paused:
            engine.pause(END_REASON)
        code = engine.participant.code
        close_rig()
        self.close()
        self._participant, self._theta_star, self._learning = None, [], None
        self._learner, self.failed = (False, None), None
        self._overview = None
        return code

    def close(self) -> None:
        """Stop the recording (it takes the last markers first), close the outlets, the engine and
        its store, release the writer lock, and wait for the learner warm-up (WARM_UP_WAIT_S)."""
        if self.recording is not None:
            self.recording.close()
            self.recording = None
        if self.outlets is not None:
            self.outlets.close()
            self.outlets = None
        if self.engine is not None:
            self.engine.close()
            self.engine = None
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        if (warming := self._warming) is not None:  # an ended session leaves no file open behind
            # it; the limit counts only this thread's own waiting (a machine held still: a VM
            # paused for 50 s once used a 10 s join up and left the warm-up's two pipes open)
            waited(lambda look: joined(warming, look), WARM_UP_WAIT_S, 0.1)
            self._warming = None

    def record(self, what: str, record: Callable[[SessionEngine], None]) -> None:
        """``record`` in the open session, if one is open."""
        if self.engine is not None:
            try:
                record(self.engine)
            except (RefusedAction, StoreError) as exc:
                log.error("%s was not recorded: %s", what, exc)

    def record_stage(self, report: StageReached, at: str) -> None:
        self.require().record_stage(report.trial_index, report.stage, report.t, at=at)

    def trial_end(self, trial_index: int, record: TrialRecord, reason: str | None,
                  actor: Actor) -> Trial | None:
        """Record the trial's end, unless it was already recorded; the trial as stored."""
        engine = self.engine
        if engine is None or engine.state.running_trial != trial_index:
            return None
        ended = engine.end_trial(trial_index, record, reason, actor, self.lab.safety_record)
        self._overview = None
        return ended

    def simulated_turn(self, step: Step, auto: bool) -> None:
        """The simulated participant acts if it is on (``auto``) and the session waits for ``step``."""
        if auto and self.engine is not None and self.engine.state.step is step:
            assert self._participant is not None, "opened with the engine, dropped when it ends"
            rate_once(self.engine, self._participant)

    def plan(self, timeout: float) -> tuple[PlannedTheta, str | None]:
        """Plan the current interaction's θ (:meth:`SessionEngine.plan_next`), and the news it
        brings for the experimenter: that learning stopped early, and why (None: no news)."""
        engine = self.require()
        before = engine.state.stopped_after
        planned = engine.plan_next(timeout)
        headline = stop_headline(engine.state)
        if before is not None or headline is None:
            return planned, None
        self._overview = None  # the Study table's count follows the shortened plan
        return planned, f"{headline}: {recorded_stop(engine.store.events())}"

    def planning(self, preparing: bool, fault: str | None) -> None:
        self._learner = (preparing, fault)

    def fail(self, reason: str) -> None:
        """The session stops with ``reason`` (the first reason stays)."""
        self.failed = self.failed or reason

    def storage_failed(self, exc: StoreWriteError) -> tuple[str, bool]:
        """A write to the study failed (a full disk): nothing of it was stored and the engine's
        state is still the stored one, but the rig and the engine may now disagree, so the session
        stops here — every further action is refused with the reason, and the worker stops — until
        it is resumed (which records a trial left running as aborted). The reason, and whether
        this is the first failure."""
        fault, first = self._store_fault, self._store_fault is None
        if fault is None:
            fault = self._store_fault = (f"{exc} (run-session --resume, or restart serve and open "
                                         "the participant)")
            self.fail(fault)
        return fault, first

    def replay_rows(self, trial_index: int) -> dict[str, np.ndarray]:
        """A stored trial as the live view's columns with the arm's links; refused while a trial
        runs."""
        engine = self.require()
        if engine.state.running_trial is not None:
            raise RefusedAction("replay refused while a trial runs")
        if not any(t.trial_index == trial_index for t in engine.store.rows("trials")):
            raise RefusedAction(f"trial {trial_index} is not a trial of {engine.participant.code}")
        rows = stored_rows(engine.store.samples(trial_index))
        if len(rows["t"]) < 2:
            raise RefusedAction(f"trial {trial_index} has no recorded samples to replay")
        return with_links(rows)

    # -- what the view shows -----------------------------------------------------------------------
    def overview(self) -> list[ParticipantSummary]:
        """Every participant of the study folder (read again after a trial's end or an open)."""
        if self._overview is None:
            engine = self.engine
            self._overview = (self._study_overview.lines() if engine is None else
                              self._study_overview.lines(engine.store, engine.participant.code))
        return self._overview

    def plan_status(self) -> PlanStatus | None:
        """The study against its plan (``[study]``): the groups' counts, the next proposal, the
        deviations (None: the lab has no plan)."""
        if self.lab.study is None:
            return None
        return PlanStatus.of(self.lab.study, [
            Participant(code=line.code, scenario=line.scenario, assignment=line.assignment)
            for line in self.overview() if line.scenario is not None])

    def facts(self) -> SessionFacts | None:
        """The open session's part of the view (None: none open)."""
        engine = self.engine
        if engine is None:
            return None
        state = engine.state
        if self._theta_star_key != len(state.planned):  # a new θ means a new learner snapshot
            self._theta_star_key = len(state.planned)
            self._theta_star = [
                ThetaStar(after_interaction=r.after_interaction, a=r.theta_star_a,
                          delta=r.theta_star_delta, k=r.theta_star_k)
                for r in engine.store.rows("learner_snapshots") if r.theta_star_a is not None]
            self._learning = learning_line(
                state, engine.config, engine.settledness, recorded_stop(engine.store.events()),
                engine.store.rows("learner_snapshots", order_by="after_interaction"), engine.gain)
        trials = engine.store.rows("trials", order_by="trial_index")
        return SessionFacts(
            code=engine.participant.code, scenario=engine.config.scenario, seed=engine.config.seed,
            state=state.model_copy(deep=True), trials=trials, theta_star=self._theta_star,
            posterior=engine.posterior_slices, learning=self._learning,
            safety_flags=self._safety_flags(trials))

    def _safety_flags(self, trials: list[Trial]) -> list[str]:
        """Each trial over the lab's [safety_record] limits, in words (newest first)."""
        flags = []
        for trial in reversed(trials):
            over = over_limits(trial.model_dump(), self.lab.safety_record)
            if over:
                flags.append(f"trial {trial.trial_index}: {'; '.join(over)}")
        return flags
