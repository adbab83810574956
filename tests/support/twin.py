"""The uninterrupted twin of a stored session: the same seed and the same handovers, never stopped.

On the wall clock (``handover serve``) two runs of one seed do not hand over identically: a trial's
arrival gap carries the machine's timing (run-session --seed 7, perturbed: interaction 1's gap
-0.0700 s on simulated time, -0.0663 s on the wall clock), and the simulated participant places on
it. The twin of a session run on the wall clock is therefore a fresh session of its configuration,
run here, in which each interaction's trial ends as the stored session's completed trial of that
interaction did, and the simulated participant places, rates and answers: whatever the stored
session's interruptions did, it must have come to exactly the twin's placements, comparisons,
answers and θ (the learner choosing each θ from the comparisons alone).
"""

from __future__ import annotations

from pathlib import Path

from app.protocol.auto import rate_once
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.protocol.study_config import StudyConfig
from robot_io.config import ControllerConfig
from robot_io.control.cycle import not_started
from robot_io.control.loop import Outcome, TrialRecord, TrialSummary
from session_store.models import Trial, TrialOutcome
from session_store.read_only_copy import reading
from session_store.store import participant_path


def replayed_record(config: ControllerConfig, trial: Trial) -> TrialRecord:
    """A stored completed trial as the controller reported it to the engine: its summary (arrival
    times and gap, speed, hold, release, pull), without samples."""
    blank = not_started(config, True, Outcome.COMPLETED, "")
    stored = trial.model_dump(include=set(TrialSummary.model_fields) - {"outcome", "reason"})
    return TrialRecord(blank.summary.model_copy(update={**stored, "reason": None}), blank.samples)


def uninterrupted_twin(database: Path, study: Path) -> Path:
    """Run the uninterrupted twin of the session stored in ``database`` in the folder ``study``;
    returns the twin's database."""
    code = database.stem
    with reading(database.parent, code) as store:
        config = StudyConfig.model_validate(store.participant().config)
        completed = {t.interaction: t for t in store.rows("trials")
                     if t.outcome is TrialOutcome.COMPLETED}
    engine = SessionEngine.create(study, code, config)
    participant = SimulatedParticipant(config.seed)
    try:
        while (step := engine.state.step) is not Step.DONE:
            if step is Step.PLAN:
                engine.plan_next()
            elif step is Step.READY:
                plan = engine.start_trial()
                trial = completed[plan.trial.interaction]
                engine.end_trial(plan.trial.trial_index, replayed_record(config.controller, trial))
            else:
                rate_once(engine, participant)
    finally:
        engine.close()
    return participant_path(study, code)
