"""The simulated participant's actions on a session: placing, hinting, rating and answering as a person would
(:func:`rate_once`, used by the session runner when "Simulated participant rates" is on)."""

from __future__ import annotations

from app.protocol.engine import SessionEngine
from app.protocol.errors import RefusedAction
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from robot_io.control.trial import simulate_trial
from session_store.models import Trial
from session_store.vocabulary import Phase, Rater


def _trial(engine: SessionEngine, interaction: int) -> Trial:
    index = engine.state.completed_trial[interaction]
    return next(t for t in engine.store.rows("trials") if t.trial_index == index)


def rate_once(engine: SessionEngine, participant: SimulatedParticipant,
              by: Rater = Rater.SIMULATED_PARTICIPANT) -> None:
    """The simulated participant places, hints, rates or answers whatever the session waits for, once;
    every row it makes is recorded as ``by``'s: the simulated participant's, or — to stand in for
    a person's answers where provenance is what is tested — the participant's or the
    experimenter's."""
    state = engine.state
    step, slot = state.step, state.slot
    if step in (Step.PLACE, Step.RATE):
        assert slot is not None, "a placement and a validation rating are of an interaction"
        if step is Step.PLACE:
            earlier = [(m, _trial(engine, m.interaction)) for m in state.markers]
            position, equal_to = participant.place(_trial(engine, slot.interaction), slot.position,
                                                   earlier)
            engine.place(position=position, equal_to=equal_to, by=by)
        else:
            engine.rate_validation(participant.rate(_trial(engine, slot.interaction - 1),
                                                    _trial(engine, slot.interaction)), by=by)
    elif step is Step.HINT:
        assert slot is not None, "a hint is about an interaction"
        engine.hint(participant.hint(_trial(engine, slot.interaction), slot.position), by=by)
    elif step is Step.ANSWER:
        best = [s.interaction for s in engine.slots if s.phase is Phase.BEST]
        best_trial = _trial(engine, best[-1]) if best else None
        question = state.unanswered[0]
        engine.answer(question, participant.answer(question, best_trial), by=by)
    else:
        raise RefusedAction(f"the simulated participant has nothing to do at {step.value!r}")



def act_once(engine: SessionEngine, participant: SimulatedParticipant,
             by: Rater = Rater.SIMULATED_PARTICIPANT) -> None:
    """Do whatever the session waits for, once, in this process, as a headless session with the
    simulated experimenter and participant would: resume a pause, plan, run a trial (one reach of
    the mock arm and the simulated hand on simulated time, without the rig process), or let the
    participant place, hint, rate or answer (:func:`rate_once`, recorded as ``by``'s)."""
    state = engine.state
    if state.paused:
        engine.resume_session()
    elif state.step is Step.PLAN:
        engine.plan_next()
    elif state.step is Step.READY:
        plan = engine.start_trial()
        record = simulate_trial(engine.config.controller, plan.theta, engine.config.scenario,
                                plan.trial.hand_seed)
        engine.end_trial(plan.trial.trial_index, record)
    else:
        rate_once(engine, participant, by)
