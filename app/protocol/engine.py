"""The study session engine: the paper's protocol as a state machine over stored events (Sect. V-C).

Every action (start a trial, end it, place it on the scale, rate a validation pair, answer, pause) is
checked against the state, written to the participant's database in one transaction (its event and its
rows together), and only then applied to the state. A refused action writes nothing. The learner runs
in its own process; its suggestions are stored as ``theta_planned`` events with a learner snapshot, so
a resumed session continues with exactly the θ an uninterrupted one would have used.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from pydantic import BaseModel

from app.learning.coactive import hinted_theta
from app.learning.models import (
    NextBatchGain,
    ParameterBox,
    PosteriorSlice,
    Settledness,
    SlotKind,
    Suggestion,
)
from app.learning.prior import PopulationPrior
from app.learning.scale import comparisons_for_newest
from app.learning.worker import LearnerClient
from app.protocol import events as ev
from app.protocol import stopping
from app.protocol.earlier import earlier_participants_prior
from app.protocol.errors import EventLogError, RefusedAction
from app.protocol.hints import DIRECTIONS
from app.protocol.plan import Slot, protocol_slots
from app.protocol.safety_record import DEFAULT_SAFETY, SafetyRecordSettings, safety_record
from app.protocol.session_inputs import hand_seed, validation_sobol
from app.protocol.session_learner import LearnerFactory, SessionLearner, scale_placement
from app.protocol.state import PlannedTheta, SessionState, Step, apply, not_running, refusal, replay
from app.protocol.study_config import StudyConfig
from robot_io.control.loop import Outcome, TrialRecord
from robot_io.control.stages import current
from robot_io.theta import Theta
from session_store.models import (
    Answer,
    Comparison,
    HintRow,
    LearnerSnapshotRow,
    Participant,
    Placement,
    Trial,
    TrialOutcome,
    ValidationRating,
    utc_now,
)
from session_store.store import ParticipantStore
from session_store.vocabulary import Actor, Hint, Phase, Rater, ThetaOrigin

log = logging.getLogger(__name__)

EventListener = Callable[[ev.ProtocolEvent, SessionState], None]
ORIGIN_OF_KIND = {SlotKind.INITIAL: ThetaOrigin.SOBOL, SlotKind.BEST: ThetaOrigin.BEST,
                  SlotKind.QUERY: ThetaOrigin.LEARNED}


class TrialPlan(BaseModel):
    trial: Trial
    theta: Theta


class SessionEngine:
    """One participant's session. Create with :meth:`create`, continue with :meth:`resume`."""

    def __init__(self, store: ParticipantStore, learner_factory: LearnerFactory) -> None:
        """The session of ``store`` as its event log leaves it (the log is validated: a log that
        breaks the protocol raises :class:`~app.protocol.errors.EventLogError` and the store is
        closed)."""
        self.store = store
        try:
            self.participant: Participant = store.participant()
            self.config: StudyConfig = StudyConfig.model_validate(self.participant.config)
            self.slots: list[Slot] = protocol_slots(self.config)
            events = store.events()
            self.state: SessionState = replay(self.slots, events)
        except BaseException:
            store.close()
            raise
        #: the GP prior from earlier participants, fixed when the session was created (or None)
        self.prior: PopulationPrior | None = next(
            (PopulationPrior.model_validate(e.payload["prior"]) for e in events
             if e.kind == "session_created" and e.payload.get("prior") is not None), None)
        self.learner = SessionLearner(store, self.config, self.slots, learner_factory)
        #: called with every event once it is stored (with its ``seq``) and the state it leads to,
        #: on the thread that acted (the study's LSL markers: app/session/lsl_outlets.py)
        self.listeners: list[EventListener] = []

    # -- lifecycle --------------------------------------------------------------------------------
    @classmethod
    def create(cls, study_dir: Path, code: str, config: StudyConfig,
               learner_factory: LearnerFactory = LearnerClient.for_session) -> SessionEngine:
        """A new session for ``code``; with ``config.population_prior`` its prior is built from
        the completed participants of ``study_dir`` first (:mod:`app.protocol.earlier`) and
        recorded with it."""
        prior = None
        if config.population_prior:
            prior = earlier_participants_prior(study_dir, code, config)
            config = config.model_copy(
                update={"prior_sources": prior.sources if prior is not None else []})
        store = ParticipantStore.create(study_dir, code, config)
        engine = cls(store, learner_factory)
        engine._commit(ev.SessionCreated(actor=Actor.EXPERIMENTER, code=code,
                                         config=config.model_dump(mode="json"),
                                         prior=None if prior is None
                                         else prior.model_dump(mode="json")))
        engine.prior = prior
        return engine

    @classmethod
    def resume(cls, study_dir: Path, code: str,
               learner_factory: LearnerFactory = LearnerClient.for_session) -> SessionEngine:
        """Reopen a session where it stopped. A trial that was running is recorded as aborted
        (it will be repeated with the same θ; the interruption is the system's, not the
        experimenter's); nothing already recorded changes. Refused while another writer holds the
        participant."""
        engine = cls(ParticipantStore.open_for_writing(study_dir, code), learner_factory)
        engine._commit(ev.SessionResumed(actor=Actor.SYSTEM, step=engine.state.step.value))
        if engine.state.running_trial is not None:
            engine.end_trial(engine.state.running_trial, None, "session interrupted")
        return engine

    @property
    def posterior_slices(self) -> list[PosteriorSlice]:
        """The posterior utility through θ* after the learner's latest reply (the dashboard's)."""
        return self.learner.posterior_slices

    @property
    def settledness(self) -> Settledness | None:
        """The stopping signal after the latest learning batch (the dashboard's), None before one."""
        return self.learner.settledness

    @property
    def gain(self) -> NextBatchGain | None:
        """What the next batch may gain over θ* after the latest learning batch (the dashboard's,
        with ``stop_when_no_gain``), None before one."""
        return self.learner.gain

    def close(self) -> None:
        self.learner.close()
        self.store.close()

    # -- the protocol's actions -----------------------------------------------------------------
    def plan_next(self, timeout: float = 60.0) -> PlannedTheta:
        """Make sure the current interaction has its θ (asking the learner if needed) and return it
        (when learning stops early, the current interaction becomes the best one)."""
        if self.state.step not in (Step.PLAN, Step.READY):
            raise RefusedAction(f"refused: the session waits for '{self.state.step.value}', not "
                                "'plan' or 'ready'")
        slot = self._current_slot()
        if self.state.step is Step.PLAN:
            if slot.learner_index is not None:
                self._plan_from_learner(slot, timeout)
            else:
                self._plan_after_learning(timeout)
        return self.state.planned[self._current_slot().interaction]

    def start_trial(self) -> TrialPlan:
        """Record the start of the current interaction's trial (the experimenter's Start)."""
        slot = self._require_slot(ev.TrialStarted)
        planned = self.state.planned[slot.interaction]
        attempt = self.state.attempts.get(slot.interaction, 0) + 1
        theta = planned.theta
        trial = Trial(trial_index=self.state.next_trial_index, interaction=slot.interaction,
                      attempt=attempt, phase=slot.phase, batch=slot.batch, position=slot.position,
                      theta_a=theta.a, theta_delta=theta.delta, theta_k=theta.k,
                      origin=planned.origin, hand_seed=hand_seed(self.config, slot.interaction),
                      started_at=utc_now())
        self._commit(ev.TrialStarted(actor=Actor.EXPERIMENTER, trial_index=trial.trial_index,
                                     interaction=slot.interaction, attempt=attempt),
                     lambda: self.store.put_trial(trial))
        return TrialPlan(trial=trial, theta=theta)

    def end_trial(self, trial_index: int, record: TrialRecord | None,
                  abort_reason: str | None = None, actor: Actor = Actor.SYSTEM,
                  safety: SafetyRecordSettings = DEFAULT_SAFETY) -> Trial:
        """Record the end of the running trial with its samples and their safety record (taken
        with the lab's ``safety`` settings). It counts as completed only if the controller completed
        the handover and nobody aborted it; otherwise it will be repeated. ``actor``: who ended it
        (the experimenter for Abort and Stop, else the system)."""
        if (why := not_running(self.state, trial_index)) is not None:
            raise RefusedAction(f"end of trial refused: {why}")
        trial = next(t for t in self.store.rows("trials") if t.trial_index == trial_index)
        summary = record.summary if record is not None else None
        completed = abort_reason is None and summary is not None and \
            summary.outcome is Outcome.COMPLETED
        not_taken = abort_reason is None and summary is not None and \
            summary.outcome is Outcome.NOT_TAKEN
        reason = abort_reason or (None if completed else
                                  f"{summary.outcome.value}: {summary.reason}" if summary else None)
        outcome = (TrialOutcome.COMPLETED if completed else
                   TrialOutcome.NOT_TAKEN if not_taken else TrialOutcome.ABORTED)
        update = {"ended_at": utc_now(), "reason": reason, "outcome": outcome,
                  "go_at": self.state.go_at}
        if summary is not None:
            update |= summary.model_dump(include={"robot_arrival_s", "hand_arrival_s",
                                                  "arrival_gap_s", "peak_speed_mps", "max_tau",
                                                  "deadline_misses", "hold_s", "release_s",
                                                  "retract_end_s", "peak_pull_n"})
        figures = None if record is None or not len(record.samples["t"]) else \
            safety_record(record.samples, safety)
        if figures is not None:
            update |= figures.model_dump()
        ended = trial.model_copy(update=update)

        def write() -> None:
            self.store.put_trial(ended)
            if record is not None:
                self.store.add_samples(trial_index, record.samples)

        self._commit(ev.TrialEnded(actor=actor, trial_index=trial_index, outcome=ended.outcome,
                                   reason=reason, safety=figures), write)
        return ended

    def record_stage(self, trial_index: int, stage: str, t: float | None,
                     at: str | None = None) -> None:
        """A stage of the running trial's handover cycle began (``t``: seconds after Go; ``at``:
        the UTC time the rig began it, which the event keeps — the Go time of the trial)."""
        if stage not in current().names:
            raise RefusedAction(f"stage {stage!r} refused: the cycle's stages are "
                                f"{', '.join(current().names)}")
        self._commit(ev.TrialStage(actor=Actor.SYSTEM, at=at or utc_now(), trial_index=trial_index,
                                   stage=stage, t=t))

    def record_devices(self, config: dict, devices: dict, rig: dict,
                       changed_from: dict | None = None) -> None:
        """The configuration in force, the devices actually opened and the ``rig`` a later resume
        compares with its own (at creation and every resume). ``changed_from``: the rig recorded
        before, when the experimenter confirmed that this session continues on a different one."""
        if changed_from is not None:
            self._commit(ev.RigChangeConfirmed(actor=Actor.EXPERIMENTER, previous=changed_from,
                                               to=rig))
        self._commit(ev.DevicesRecorded(actor=Actor.SYSTEM, config=config, devices=devices,
                                        rig=rig))

    def switch_simulated_participant(self, on: bool) -> None:
        """The experimenter switches the simulated participant on (it rates from now on) or off
        (the participant does); recorded, so every later rating's origin is known."""
        if self.state.simulated_participant != on:
            self._commit(ev.SimulatedParticipantSwitched(actor=Actor.EXPERIMENTER, on=on))

    def set_blinding(self, blind: bool) -> None:
        """The dashboard serving this session hides the θ and origin of validation trials (``blind``)
        or shows them; recorded when it differs from the last record (at the first open, and when a
        restart changes it), so the report can say how the validation was run."""
        if self.state.blind != blind:
            self._commit(ev.ValidationBlindingSet(actor=Actor.EXPERIMENTER, blind=blind))

    def place(self, position: float | None = None, equal_to: int | None = None,
              by: Rater = Rater.PARTICIPANT) -> list[Comparison]:
        """The participant's placement of the last interaction on the relative scale: a position
        in [0, 1] ("Strongly Worse" … "Strongly Better") or ``equal_to`` an earlier marker of the
        batch; ``by`` whom (its provenance). Returns the comparisons it adds (newest against every
        earlier one; ties none)."""
        slot = self._require_slot(ev.PlacementMade)
        markers = {m.interaction: m for m in self.state.markers}
        if equal_to is not None:
            if equal_to not in markers:
                raise RefusedAction(f"equal_to = {equal_to} is not an interaction on the scale of "
                                    f"this batch (on the scale: {sorted(markers)})")
            position = markers[equal_to].position
        if position is None or not 0.0 <= position <= 1.0:
            raise RefusedAction(f"position = {position!r} is outside the scale [0.0, 1.0]")
        scale = [scale_placement(m.interaction, m.position, m.equal_to) for m in self.state.markers]
        scale.append(scale_placement(slot.interaction, position, equal_to))
        learned = comparisons_for_newest(scale, ties=True)  # the learner drops or models ties
        comparisons = [Comparison(batch=slot.batch, source=slot.interaction, winner=int(c.winner),
                                  loser=int(c.loser)) for c in learned if not c.tie]
        trial_index = self.state.completed_trial[slot.interaction]
        placement = Placement(trial_index=trial_index, interaction=slot.interaction,
                              batch=slot.batch, position=position, equal_to=equal_to, actor=by)

        def write() -> None:
            self.store.add(placement)
            for comparison in comparisons:
                self.store.add(comparison)

        self._commit(ev.PlacementMade(actor=by.actor, trial_index=trial_index,
                                      interaction=slot.interaction, position=position,
                                      equal_to=equal_to,
                                      comparisons=[(c.winner, c.loser) for c in comparisons]),
                     write)
        if not self.state.coactive:  # else the hint that follows completes what the learner gets
            self.learner.teach(self.state, slot, learned, None)
        return comparisons

    def hint(self, hint: Hint | None, by: Rater = Rater.PARTICIPANT) -> HintRow:
        """The participant's coactive hint about the handover just placed (``[protocol]
        coactive``): which way the robot should change, or None for "nothing"; ``by`` whom. The
        learner gets the placement's comparisons and θ' ≻ θ, θ' the handover's θ moved along the
        hint by ``hint_step`` of the parameter's range (:mod:`app.protocol.hints`)."""
        slot = self._require_slot(ev.HintGiven)
        theta = self.state.planned[slot.interaction].theta
        hinted = None if hint is None else hinted_theta(
            theta.model_dump(), ParameterBox.from_bounds(self.config.theta_bounds),
            DIRECTIONS[hint], self.config.hint_step)
        row = HintRow(trial_index=self.state.completed_trial[slot.interaction],
                      interaction=slot.interaction, batch=slot.batch, hint=hint,
                      step=self.config.hint_step,
                      hinted_a=None if hinted is None else hinted["a"],
                      hinted_delta=None if hinted is None else hinted["delta"],
                      hinted_k=None if hinted is None else hinted["k"], actor=by)
        scale = [scale_placement(m.interaction, m.position, m.equal_to) for m in self.state.markers]
        self._commit(ev.HintGiven(actor=by.actor, trial_index=row.trial_index,
                                  interaction=slot.interaction, hint=hint, hinted=hinted),
                     lambda: self.store.add(row))
        self.learner.teach(self.state, slot, comparisons_for_newest(scale, ties=True), row)
        return row

    def rate_validation(self, rating: str, by: Rater = Rater.PARTICIPANT) -> ValidationRating:
        """The second interaction of a validation pair, rated against the first (``by`` whom)."""
        slot = self._require_slot(ev.ValidationRated)
        if rating not in ("better", "worse", "equal"):
            raise RefusedAction(f"rating = {rating!r} is not one of 'better', 'worse', 'equal'")
        learned_second = slot.origin is ThetaOrigin.BEST
        preferred = None if rating == "equal" else (rating == "better") == learned_second
        row = ValidationRating(batch=slot.batch, trial_index=self.state.completed_trial[
            slot.interaction], interaction=slot.interaction, rating=rating,
            learned_preferred=preferred, actor=by)
        self._commit(ev.ValidationRated(actor=by.actor, interaction=slot.interaction, rating=rating),
                     lambda: self.store.add(row))
        return row

    def answer(self, question: str, value: str, by: Rater = Rater.PARTICIPANT) -> Answer:
        """An answer to a question of the questionnaire (``by`` whom)."""
        self._require(ev.AnswerGiven)
        row = Answer(question=question, value=str(value), actor=by)
        self._commit(ev.AnswerGiven(actor=by.actor, question=question, value=row.value),
                     lambda: self.store.add(row))
        return row

    def record_not_used(self, event: ev.EntryNotUsed) -> None:
        """An answer that came after another for the same prompt: recorded, not used
        (:mod:`app.protocol.entries`)."""
        self._commit(event)

    def pause(self, reason: str = "") -> None:
        self._commit(ev.Paused(actor=Actor.EXPERIMENTER, reason=reason))

    def resume_session(self, reason: str = "") -> None:
        """The experimenter resumes the paused session (``reason``: how, when not by Resume)."""
        self._commit(ev.Resumed(actor=Actor.EXPERIMENTER, reason=reason))

    def pause_reason(self) -> str | None:
        """Why the session is paused, as recorded (None: it is not paused)."""
        if not self.state.paused:
            return None
        return next(e.payload.get("reason", "") for e in reversed(self.store.events())
                    if e.kind == "paused")

    # -- internals ---------------------------------------------------------------------------------
    def _require(self, kind: type[ev.ProtocolEvent]) -> None:
        """Refuse the action unless the session waits for an event of ``kind`` (the protocol's
        rule, :func:`~app.protocol.state.refusal`)."""
        if (why := refusal(self.state, kind)) is not None:
            raise RefusedAction(f"refused: {why}")

    def _require_slot(self, kind: type[ev.ProtocolEvent]) -> Slot:
        """:meth:`_require` for an event taken at an interaction, and that interaction's slot."""
        self._require(kind)
        return self._current_slot()

    def _current_slot(self) -> Slot:
        slot = self.state.slot
        assert slot is not None, f"the session at '{self.state.step.value}' is past its last slot"
        return slot

    def _commit(self, event: ev.ProtocolEvent, *writes: Callable[[], None]) -> None:
        """Check ``event`` against a copy of the state (a breach raises and writes nothing), write
        it with its rows in one transaction, then make the copy the state."""
        self._commit_all([event], *writes)

    def _commit_all(self, events: list[ev.ProtocolEvent], *writes: Callable[[], None]) -> None:
        state = self.state.model_copy(deep=True)
        for event in events:
            try:
                apply(state, event)
            except EventLogError as breach:  # a new event: the protocol refuses the action
                raise RefusedAction(f"{event.kind} refused: {breach.problem}") from None
        with self.store.transaction():
            stored = [self.store.append_event(ev.to_row(event)).seq for event in events]
            last = stored[-1]
            assert last is not None, "append_event numbers the event it stores"
            state.last_event = last
            for write in writes:
                write()
        self.state = state
        for event, seq in zip(events, stored, strict=True):
            for listener in self.listeners:
                try:
                    listener(event.model_copy(update={"seq": seq}), state)
                except Exception:  # the event is stored: a listener's failure must not undo the action
                    log.exception("a listener of event %d (%s) failed", seq, event.kind)

    def _stored(self, row: LearnerSnapshotRow | None) -> list[Callable[[], None]]:
        """The write of ``row`` for a commit (none without a row)."""
        return [] if row is None else [lambda: self.store.add(row)]

    def _plan_from_learner(self, slot: Slot, timeout: float) -> None:
        suggestion, learner = self.learner.suggestion(self.state, self.prior, timeout)
        if suggestion.theta is None or suggestion.slot.index != slot.learner_index:
            raise RefusedAction(f"learner answered for slot {suggestion.slot.index}, the session "
                                f"needs slot {slot.learner_index}")
        checked = self._checked(slot, suggestion, learner)
        stop = next((e for e in checked if isinstance(e, ev.LearningStopped)), None)
        if stop is not None:
            self._commit_all(list(checked))
            log.info("learning stopped after interaction %d: %s", stop.after_interaction,
                     stop.reason)
            self._plan_learned(suggestion, learner)
            return
        theta = Theta(**suggestion.theta)
        origin = ORIGIN_OF_KIND[suggestion.slot.kind]
        row = self.learner.snapshot_row(learner, slot.interaction - 1, suggestion)
        self._commit_all([*checked, ev.ThetaPlanned(actor=Actor.LEARNER,
                                                    interaction=slot.interaction,
                                                    **theta.model_dump(), origin=origin,
                                                    fallback=suggestion.fallback,
                                                    fit_failed=suggestion.fit.fit_failed)],
                         *self._stored(row))

    def _checked(self, slot: Slot, suggestion: Suggestion, learner: LearnerClient
                 ) -> list[ev.LearningChecked | ev.LearningStopped]:
        """At the opening of a learning batch, with a stopping rule: the check of the batch just
        ended from the learner's latest reply (none after a fallback: no signal), and the stop if
        the rule stops learning (:mod:`app.protocol.stopping`)."""
        if slot.phase is not Phase.LEARNING or slot.position != 1 or suggestion.fallback:
            return []
        return stopping.check(self.config, slot.interaction - 1, slot.batch - 1,
                              learner.settledness, learner.gain)

    def _plan_after_learning(self, timeout: float) -> None:
        """θ* of the finished learning phase for the best and validation interactions, and the
        Sobol references of validation, all planned at once (with a stopping rule, the check of
        the last batch too, which stops nothing)."""
        suggestion, learner = self.learner.suggestion(self.state, self.prior, timeout)
        last = [s for s in self.slots if s.learner_index is not None]
        checked = [] if suggestion.fallback or self.state.stopped_after or not last else \
            stopping.check(self.config, last[-1].interaction, last[-1].batch, learner.settledness,
                           learner.gain, may_stop=False)
        self._plan_learned(suggestion, learner, checked)

    def _plan_learned(self, suggestion: Suggestion, learner: LearnerClient,
                      checked: list[ev.LearningChecked | ev.LearningStopped] | None = None) -> None:
        """Plan the best and validation interactions from the learner's latest reply (with the
        check of the last batch, ``checked``, in the same transaction)."""
        if learner.best is None:
            raise RefusedAction("the learner has no θ* yet")
        best = Theta(**learner.best.theta)
        references = iter(validation_sobol(self.config))
        remaining = [s for s in self.slots if s.learner_index is None
                     and s.interaction not in self.state.planned]
        after = self.state.stopped_after or remaining[0].interaction - 1
        row = self.learner.snapshot_row(learner, after, suggestion)
        events: list[ev.ProtocolEvent] = list(checked or [])
        for slot in remaining:
            theta = best if slot.origin is ThetaOrigin.BEST else next(references)
            events.append(ev.ThetaPlanned(actor=Actor.LEARNER, interaction=slot.interaction,
                                          **theta.model_dump(), origin=slot.origin))
        self._commit_all(events, *self._stored(row))
        self.learner.close()  # learning is done
