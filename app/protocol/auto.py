"""A whole session headless: the engine drives the protocol, the controller runs each handover on the
mock arm on simulated time, and the simulated participant rates and answers."""

from __future__ import annotations

import sys

from tqdm import tqdm

from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from robot_io.trial import simulate_trial
from session_store.models import QUESTIONS, Phase, Trial


def _trial(engine: SessionEngine, interaction: int) -> Trial:
    index = engine.state.completed_trial[interaction]
    return next(t for t in engine.store.rows("trials") if t.trial_index == index)


def step_once(engine: SessionEngine, participant: SimulatedParticipant) -> None:
    """Do whatever the session waits for, once."""
    state = engine.state
    step, slot = state.step, state.slot
    if state.paused:
        engine.resume_session()
    elif step is Step.PLAN:
        engine.plan_next()
    elif step is Step.READY:
        plan = engine.start_trial()
        record = simulate_trial(engine.config.controller, plan.theta, engine.config.scenario,
                                plan.trial.hand_seed)
        engine.end_trial(plan.trial.trial_index, record)
    elif step is Step.PLACE:
        earlier = [(m, _trial(engine, m.interaction)) for m in state.markers]
        position, equal_to = participant.place(_trial(engine, slot.interaction), slot.position,
                                               earlier)
        engine.place(position=position, equal_to=equal_to)
    elif step is Step.RATE:
        engine.rate_validation(participant.rate(_trial(engine, slot.interaction - 1),
                                                _trial(engine, slot.interaction)))
    elif step is Step.ANSWER:
        best = [s.interaction for s in engine.slots if s.phase is Phase.BEST]
        best_trial = _trial(engine, best[-1]) if best else None
        question = next(q.id for q in QUESTIONS if q.id not in state.answers)
        engine.answer(question, participant.answer(question, best_trial))


def run_auto(engine: SessionEngine, participant: SimulatedParticipant, progress: bool = True) -> None:
    """Run the session to its end (a resumed one from where it stopped)."""
    with tqdm(total=engine.config.interactions, initial=engine.state.completed, unit="handover",
              disable=not progress, file=sys.stderr, desc=engine.participant.code) as bar:
        while engine.state.step is not Step.DONE:
            before = engine.state.completed
            step_once(engine, participant)
            bar.update(engine.state.completed - before)
