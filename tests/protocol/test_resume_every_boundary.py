"""Exact resume at every step boundary of the protocol: the short one with two validation pairs (3
initial, a learning batch of 3, 1 best, the questionnaire, 2 validation pairs: a rating followed by
a next trial) has every kind of boundary of the paper's (Sect. V-C: 5 initial, 4 batches of 5, 1
best, the questionnaire, 4 validation pairs), in a third of its interactions. The paper's 34 ran
here until the suite had to fit in 12 minutes (195 s of a 3-worker run); they run end to end in
tests/protocol/test_resume_exact.py (uninterrupted and killed).

One session runs uninterrupted. A second, with the same seed, crashes and resumes after every engine
action (:func:`_crashes_here` says which two boundaries alternate): between plan and start, between
start and end (the running trial is then recorded as interrupted and repeated with the same θ),
between trial end and placement, between placement and the next plan, between ratings and answers.
Each resume is a fresh ``SessionEngine`` and a fresh learner process restored from the database
alone, in the same test process. The model of a crash: the learner process is killed (SIGKILL) and
nothing survives but what was committed — every engine action commits before it returns, and the
SIGKILL tests in ``tests/test_resume_exact.py`` show that a kill of the writing process leaves
exactly the committed state. Both sessions must plan the same θ for every interaction and store the
same learner snapshots (θ*, ``n_points``, ``n_comparisons``).
"""

from __future__ import annotations

import os
import signal
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from support.engine import SHORT_PROTOCOL, study_config

from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step
from app.protocol.study_config import StudyConfig
from robot_io.control.trial import simulate_trial
from robot_io.hands.simulated_hand import Scenario
from session_store.vocabulary import QUESTIONS, Phase

CODE = "B01"


def _trial(engine: SessionEngine, interaction: int):
    index = engine.state.completed_trial[interaction]
    return next(t for t in engine.store.rows("trials") if t.trial_index == index)


def _act(engine: SessionEngine, participant: SimulatedParticipant, running: dict) -> str:
    """One engine action (each a boundary of its own); returns its name."""
    state = engine.state
    step, slot = state.step, state.slot
    if step is Step.PLAN:
        engine.plan_next()
        return "plan"
    if step is Step.READY:
        plan = engine.start_trial()
        running["plan"] = plan
        return "start"
    if step is Step.RUNNING:
        plan = running.pop("plan")
        record = simulate_trial(engine.config.controller, plan.theta, engine.config.scenario,
                                plan.trial.hand_seed)
        engine.end_trial(plan.trial.trial_index, record)
        return "end"
    if step is Step.PLACE:
        earlier = [(m, _trial(engine, m.interaction)) for m in state.markers]
        position, equal_to = participant.place(_trial(engine, slot.interaction), slot.position,
                                               earlier)
        engine.place(position=position, equal_to=equal_to)
        return "place"
    if step is Step.RATE:
        engine.rate_validation(participant.rate(_trial(engine, slot.interaction - 1),
                                                _trial(engine, slot.interaction)))
        return "rate"
    best = [s.interaction for s in engine.slots if s.phase is Phase.BEST]
    question = next(q.id for q in QUESTIONS if q.id not in state.answers)
    engine.answer(question, participant.answer(question, _trial(engine, best[-1])))
    return "answer"


def _crash(engine: SessionEngine) -> None:
    """What a crash leaves: the learner process dies (SIGKILL), the database holds what was
    committed (every action commits before it returns), the engine is gone."""
    if engine.learner.pid is not None:
        os.kill(engine.learner.pid, signal.SIGKILL)  # close() below then finds it dead at once
    engine.close()


def _crashes_here(action: str, step: Step, interaction: int | None) -> bool:
    """Every boundary, at every interaction — except that the two after which the learner must be
    restored (trial end → placement, placement → next plan) alternate between odd and even
    interactions: each restore costs a learner process (BoTorch's import), and each boundary is
    still crashed at a dozen times across all batches."""
    if (action, step) == ("end", Step.PLACE):
        return interaction % 2 == 1
    if (action, step) == ("place", Step.PLAN):
        return interaction % 2 == 0
    return True


def _run(study: Path, config: StudyConfig, crash: bool) -> set[tuple[str, str]]:
    """The whole session; returns the boundaries (action before → step after) crashed at. Each
    boundary is crashed at once (a crash while a trial runs repeats the trial: crashing again at
    the repeat would never end)."""
    participant, running, seen = SimulatedParticipant(config.seed), {}, set()
    engine = SessionEngine.create(study, CODE, config)
    try:
        while engine.state.step is not Step.DONE:
            action = _act(engine, participant, running)
            state = engine.state
            interaction = state.slot.interaction if state.slot else None
            where = (action, state.step.value, interaction, len(state.answers))
            if crash and state.step is not Step.DONE and where not in seen and \
                    _crashes_here(action, state.step, interaction):
                seen.add(where)
                _crash(engine)
                running.clear()  # the trial that ran is lost with the process
                engine = SessionEngine.resume(study, CODE)
    finally:
        engine.close()
    return {(action, step) for action, step, *_ in seen}


def _planned_and_snapshots(study: Path) -> tuple[np.ndarray, list[tuple]]:
    with sqlite3.connect(study / f"{CODE}.sqlite") as conn:
        planned = conn.execute(
            "SELECT json_extract(payload, '$.interaction'), json_extract(payload, '$.a'), "
            "json_extract(payload, '$.delta'), json_extract(payload, '$.k') FROM events "
            "WHERE kind = 'theta_planned' ORDER BY json_extract(payload, '$.interaction')").fetchall()
        snapshots = conn.execute(
            "SELECT after_interaction, n_points, n_comparisons, fit_failed, theta_star_a, "
            "theta_star_delta, theta_star_k FROM learner_snapshots ORDER BY after_interaction"
        ).fetchall()
    return np.array(planned, dtype=float), snapshots


@pytest.mark.slow
def test_a_crash_at_every_step_boundary_of_the_protocol_gives_the_uninterrupted_thetas(tmp_path):
    """Slow (~20 s in a loaded full run): the short protocol twice, once whole and once crashed at
    every step boundary, each crash restoring a learner process (:func:`_crashes_here`)."""
    config = study_config(21, Scenario.PERTURBED, **SHORT_PROTOCOL | {"validation_batches": 2})
    _run(tmp_path / "whole", config, crash=False)
    crashed = _run(tmp_path / "crashed", config, crash=True)
    assert crashed >= {("plan", "ready"), ("start", "running"), ("end", "place"), ("place", "plan"),
                       ("end", "answer"), ("answer", "answer"), ("answer", "ready"), ("end", "ready"),
                       ("end", "rate"), ("rate", "ready")}, crashed
    assert_same_thetas_and_snapshots(tmp_path / "whole", tmp_path / "crashed", config.interactions)


def assert_same_thetas_and_snapshots(whole: Path, crashed: Path, interactions: int) -> None:
    """Bit for bit: every learner process runs the same code on the same data in the same order.
    (Fed its comparisons in key order after a resume, the learner differed from interaction 9 on:
    by 8e-15 relative there, 9e-9 at interaction 23.)"""
    whole_theta, whole_snapshots = _planned_and_snapshots(whole)
    theta, snapshots = _planned_and_snapshots(crashed)
    assert len(whole_theta) == len(theta) == interactions
    differing = [int(row[0]) for row, other in zip(theta, whole_theta, strict=True)
                 if not np.array_equal(row, other)]
    assert differing == [], f"θ planned differently for interactions {differing}"
    assert snapshots == whole_snapshots
    assert all(n_points > 0 for _, n_points, *_ in snapshots[2:])  # from the first comparison on
