"""The trial supervisor: the open session's rig process, its reports, and the arm's state the
experimenter acts on — armed, stopping or stopped (STOP ARM and Re-arm), its fault (until Recover
arm), why the hand is not ready at A, late timing, the hand's link, the running trial's plan and
who ended it.

That state is written from three threads: the engine thread (a rig opened, a trial started), the
screens' threads (Stop, Abort, Re-arm, Recover) and the rig's reader thread (its reports). Every
write, and every read that decides something, is under the supervisor's one lock
(``TrialSupervisor._state_lock``), which is never held while waiting for an answer: not for the rig's
acknowledgement of a Stop, not for a recovery, not for the engine. What a report means for the
session — a stage or a trial's end to record — is handed to the session (:class:`Recording`), which
records it on the engine thread (docs/architecture.md, "Threads and who owns what")."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from app.protocol.engine import TrialPlan
from app.protocol.errors import RefusedAction
from app.session.drawing import with_links
from app.session.lsl_outlets import StudyOutlets
from app.session.rehearsal import Rehearsal
from app.session.view import RigStatus, StopState
from robot_io.config import ControllerConfig
from robot_io.control.cycle import not_started
from robot_io.control.loop import Outcome, TrialRecord
from robot_io.control.stages import Stage
from robot_io.errors import RobotIOError, explain
from robot_io.hands.simulated_hand import Scenario
from robot_io.rig.client import RigClient
from robot_io.rig.messages import (
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
from session_store.models import Trial
from session_store.vocabulary import Actor

log = logging.getLogger(__name__)

#: The reasons recorded with a trial the experimenter aborted or stopped.
ABORT_REASON = "aborted by the experimenter"
STOP_REASON = "stopped by the experimenter (Stop)"


class Recording(NamedTuple):
    """What the supervisor hands to the session (the session runner records on its engine thread)."""

    #: a stage the rig reached: record it, then publish
    stage: Callable[[StageReached], None]
    #: a trial's end (index, record, reason, by whom): record it unless it already is; the trial as
    #: stored, or None; raises RefusedAction when it cannot be stored (the session stopped)
    trial_end: Callable[[int, TrialRecord, str | None, Actor], Trial | None]
    #: the open session's LSL outlets (None: none)
    outlets: Callable[[], StudyOutlets | None]
    #: a change with its message for the log (None: none): a new view made on the engine thread
    changed: Callable[[str | None], None]
    #: device news: published at once over the view shown, without waiting for the engine thread
    news: Callable[[str | None], None]


class TrialSupervisor:
    """The rig process of the open session and the arm's state; see the module's docstring."""

    def __init__(self, recording: Recording, *, realtime: bool, realtime_priority: bool,
                 rehearsal: Rehearsal | None) -> None:
        self._recording = recording
        self._realtime, self._realtime_priority = realtime, realtime_priority
        self._rehearsal = rehearsal
        self._state_lock = threading.Lock()
        self._rig: RigClient | None = None
        self._status = RigStatus()
        self._plan: TrialPlan | None = None
        self._abort_reason: str | None = None
        self._abort_actor = Actor.SYSTEM
        self._closed = False  # close() has begun: no rig opens any more

    # -- reading (any thread, never blocks) --------------------------------------------------------
    @property
    def rig(self) -> RigClient | None:
        return self._rig

    @property
    def alive(self) -> bool:
        """Whether a rig process is open and running."""
        rig = self._rig
        return rig is not None and rig.alive

    def status(self) -> RigStatus:
        return self._status

    def live(self, stride: int) -> tuple[TrialPlan | None, dict[str, np.ndarray] | None]:
        """The running (or last) trial and its rows so far with the arm's links."""
        rig, plan = self._rig, self._plan
        if rig is None or plan is None or rig.stream.trial_index != plan.trial.trial_index:
            return plan, None
        return plan, with_links(rig.stream.view(stride))

    def _set(self, **fields: Any) -> None:
        """Change the status (under the lock)."""
        self._status = self._status._replace(**fields)

    # -- the rig process (engine thread) -----------------------------------------------------------
    def open(self, config: ControllerConfig, scenario: Scenario) -> None:
        """Start a rig process for the session (the previous one, if any, is closed)."""
        with self._state_lock:
            previous, self._rig = self._rig, None
        if previous is not None:
            previous.close()
        spec = RigSpec(config=config, scenario=scenario, realtime=self._realtime,
                       realtime_priority=self._realtime_priority)
        try:
            rig = RigClient(spec, self._on_report)
        except (RobotIOError, OSError) as exc:
            with self._state_lock:
                self._set(fault=explain(exc))
            raise RefusedAction(f"the rig could not start: {explain(exc)}") from exc
        with self._state_lock:
            closed = self._closed
            if not closed:
                self._rig = rig
                self._set(devices=rig.devices, fault=None, timing=None, hand_link=None)
        if closed:  # the session closed while this rig started: it never runs a trial
            rig.close()
            raise RefusedAction("the session closed while its rig started")

    def close_rig(self) -> None:
        """Close the rig process at the end of a session."""
        with self._state_lock:
            rig, self._rig, self._plan = self._rig, None, None
            self._set(devices=None)
        if rig is not None:
            rig.close()

    def refuse_unless_armed(self) -> None:
        if self._status.stop != "armed":
            raise RefusedAction("Start refused: the arm was stopped (STOP ARM); make sure the scene "
                                "is safe, then press Re-arm")

    def ready_rig(self, config: ControllerConfig, scenario: Scenario) -> None:
        """A fresh rig process if the last one died; refused while the arm has a fault."""
        if not self.alive:
            self.open(config, scenario)
        elif (fault := self._status.fault) is not None:
            raise RefusedAction(f"Start refused: the arm has a fault ({fault}); inspect it, then "
                                "press Recover arm")

    def run(self, plan: TrialPlan, automatic: bool) -> None:
        """Send ``plan``'s trial to the rig (``automatic``: no confirmation of the cycle to wait for).
        Refused if a Stop came since Start was checked: the lock makes a Stop land either before
        (refused here) or after the rig has the trial (the Stop ends it). Held over the send only
        (the rig's inbox reads commands at once)."""
        with self._state_lock:
            self.refuse_unless_armed()
            self._plan, self._abort_reason, self._abort_actor = plan, None, Actor.SYSTEM
            self._set(ready_wait=None)
            rig = self._rig
            assert rig is not None, "ready_rig opened it on this (the engine) thread"
            rig.run_trial(RunTrial(trial_index=plan.trial.trial_index, theta=plan.theta,
                                   hand_seed=plan.trial.hand_seed, automatic=automatic))

    # -- the experimenter (screens' threads; never wait for the engine) -----------------------------
    def _halting(self, reason: str) -> RigClient | None:
        """Under the lock: the rig to stop, and the reason its running trial is recorded with."""
        rig = self._rig
        if rig is not None and rig.running is not None and self._abort_reason is None:
            self._abort_reason, self._abort_actor = reason, Actor.EXPERIMENTER
        return rig

    def abort(self) -> None:
        """End the running trial now; it is recorded as aborted by the experimenter."""
        with self._state_lock:
            if self._plan is None or self._rig is None or self._rig.running is None:
                raise RefusedAction("abort refused: no trial is running")
            rig = self._halting(ABORT_REASON)
        assert rig is not None, "checked above under the lock"
        rig.stop(ABORT_REASON)

    def stop(self) -> str:
        """STOP ARM: "stopping" before the rig is told (its trial's end makes it "stopped"), at
        once "stopped" when no trial runs; the message for the log."""
        with self._state_lock:
            self._set(stop="stopping")
            rig = self._halting(STOP_REASON)
        if rig is not None:
            rig.stop(STOP_REASON)
        with self._state_lock:
            if self._status.stop == "stopping" and (self._rig is None or self._rig.running is None):
                self._set(stop="stopped")
            stopped = self._status.stop == "stopped"
        return "Stop: the arm is stopped" if stopped else "STOP ARM: the arm is stopping"

    def rearm(self) -> None:
        """The scene is safe again: trials may start (refused unless the arm is stopped)."""
        with self._state_lock:
            state: StopState = self._status.stop
            if state == "stopping":
                raise RefusedAction("re-arm refused: the arm is still stopping")
            if state == "armed":
                raise RefusedAction("re-arm refused: the arm was not stopped")
            self._set(stop="armed")

    def recover(self, inspected: bool) -> str:
        """Clear the arm's fault on the open rig (moves nothing); the rig's message."""
        rig = self._rig
        if rig is None:
            raise RefusedAction("recover refused: no rig is open")
        if rig.running is not None:
            raise RefusedAction("recover refused while a trial runs: Stop it first")
        try:
            result = rig.recover(inspected)
        except RobotIOError as exc:
            raise RefusedAction(str(exc)) from exc
        if not result.ok:
            raise RefusedAction(result.message)
        with self._state_lock:
            self._set(fault=None)
        return result.message

    def close(self, reason: str) -> None:
        """Stop the arm first (a running trial is recorded aborted with ``reason``), then close the
        rig and wait until its last reports are handed on."""
        with self._state_lock:
            self._closed = True
            rig = self._rig
            if rig is not None and rig.running is not None:
                self._abort_reason = self._abort_reason or reason
        if rig is None:
            return
        if rig.running is not None:
            rig.stop(reason)
        rig.close()
        if not rig.reports_handed_on():  # the stopped trial's end is recorded before the engine closes
            log.error("the rig's last reports were not all handed on: a trial left running is "
                      "recorded aborted when the session resumes")

    # -- the rig's reports (its reader thread) -----------------------------------------------------
    def _on_report(self, rig: RigClient, report: Report | RigDied) -> None:
        """``rig``'s report. A trial's end is recorded from whichever rig ran it; what the other
        reports say of the arm is dropped when they come from a rig already replaced."""
        if isinstance(report, TrialDone):
            self._on_trial_done(rig, report)
        elif isinstance(report, RigDied):
            self._on_death(rig, report)
        elif rig is not self._rig:
            log.info("a report of a closed rig left out: %s", type(report).__name__)
        elif isinstance(report, StageReached):
            self._on_stage(rig, report)
        elif isinstance(report, ReadyWaiting):
            with self._state_lock:
                self._set(ready_wait=report.why)
            self._recording.changed(None)
        elif isinstance(report, RigTiming):
            self._on_timing(report)
        elif isinstance(report, HandLink):
            with self._state_lock:
                self._set(hand_link=report.notice)
            self._recording.news(None)

    def _on_trial_done(self, rig: RigClient, report: TrialDone) -> None:
        with self._state_lock:
            timing = self._status.timing
            if timing is not None and timing.trial_index != report.trial_index:
                self._set(timing=None)  # this trial ran on time
        self._flush_outlets()
        self._finish(report.trial_index, TrialRecord(report.summary, rig.stream.columns()))

    def _on_timing(self, report: RigTiming) -> None:
        with self._state_lock:
            timing = self._status.timing
            first = timing is None or timing.trial_index != report.trial_index
            self._set(timing=report)
        # on stderr (headless too) as it begins and as the trial ended, the figures the dashboard
        # then keeps by the devices
        if first or report.final:
            log.warning("%s", report.describe())
        self._recording.changed(f"trial {report.trial_index}: the rig's timing runs late (see "
                                "Devices)" if first else None)

    def _on_death(self, rig: RigClient, report: RigDied) -> None:
        with self._state_lock:
            if rig is self._rig:
                self._set(fault=report.reason)
            reason = self._abort_reason or report.reason
        self._flush_outlets()
        if report.trial_index is not None:
            record = not_started(rig.spec.config, self._realtime, Outcome.ERROR, report.reason)
            self._finish(report.trial_index, TrialRecord(record.summary, rig.stream.columns()),
                         reason)
            return
        self._stopped()
        self._recording.changed(report.reason)

    def _flush_outlets(self) -> None:
        """The robot stream gets the rest of the trial's rows before anything else happens."""
        outlets = self._recording.outlets()
        if outlets is not None:
            outlets.feed.flush()

    def _on_stage(self, rig: RigClient, report: StageReached) -> None:
        with self._state_lock:
            plan = self._plan
            if report.stage == Stage.READY:
                self._set(ready_wait=None)
        outlets = self._recording.outlets()
        if report.stage == Stage.GO and outlets is not None:
            outlets.feed.go(report.trial_index, report.monotonic)
        if report.stage == Stage.GO and self._rehearsal is not None and plan is not None:
            assert rig.spec.scenario is not None, \
                "the rig that reports its plan's trial, opened with the session's scenario"
            self._rehearsal.play(rig.spec.scenario, plan.trial.hand_seed, report.monotonic)
        self._recording.stage(report)

    def _stopped(self) -> None:
        """The arm has stopped (its trial is over): a Stop that was under way is complete."""
        with self._state_lock:
            if self._status.stop == "stopping":
                self._set(stop="stopped")

    def _finish(self, trial_index: int, record: TrialRecord, reason: str | None = None) -> None:
        if self._rehearsal is not None:
            self._rehearsal.rest()
        summary = record.summary
        with self._state_lock:
            # A fault of the arm or of the gripper locks Start until the experimenter has inspected
            # it: after a gripper fault mid-hold the arm holds the object out where it stopped, and
            # the next Start's prepare would move it back to R with the object.
            if summary.outcome in (Outcome.ARM_FAULT, Outcome.GRIPPER_FAULT) or summary.retract_fault:
                self._set(fault=summary.retract_fault or summary.reason)
            reason = reason or self._abort_reason
            actor = self._abort_actor if reason is not None else Actor.SYSTEM
        try:
            ended = self._recording.trial_end(trial_index, record, reason, actor)
        except RefusedAction as exc:  # not stored (the session stopped): resuming repeats it
            log.error("trial %d's end not recorded: %s", trial_index, exc)
            return
        self._stopped()
        message = None
        if ended is not None:
            assert ended.outcome is not None, "a trial's end is stored with its outcome"
            message = (f"trial {ended.trial_index} {ended.outcome.value}"
                       + (f": {ended.reason}" if ended.reason else ""))
        self._recording.changed(message)
