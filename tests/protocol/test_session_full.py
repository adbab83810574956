"""A whole headless session with the paper's defaults (Sect. V-C): 5 + 20 + 1 + 8 interactions."""

from __future__ import annotations

import numpy as np
import pytest
from support.engine import drive_until, study_config

from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant
from app.protocol.state import Step, replay
from robot_io.hands.simulated_hand import Scenario
from session_store.vocabulary import Phase, question


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    study = tmp_path_factory.mktemp("study")
    engine = SessionEngine.create(study, "P01", study_config(3, Scenario.PERTURBED))
    drive_until(engine, Step.DONE, SimulatedParticipant(3))
    yield engine
    engine.close()


def test_all_34_interactions_complete_in_the_papers_phases(session):
    """Slow (~20 s in a loaded full run) as the module's first test: it pays for the ``session``
    fixture, a whole session of the paper's 34 interactions with its learner."""
    trials = [t for t in session.store.rows("trials") if t.outcome == "completed"]
    assert len(trials) == 34 and session.state.step is Step.DONE
    by_phase = {phase: sum(t.phase == phase for t in trials) for phase in Phase}
    assert by_phase[Phase.INITIAL] == 5 and by_phase[Phase.LEARNING] == 20
    assert by_phase[Phase.BEST] == 1 and by_phase[Phase.VALIDATION] == 8
    assert sorted(t.interaction for t in trials) == list(range(1, 35))


def test_comparisons_are_exactly_those_the_scale_rule_implies(session):
    """Newest against each earlier marker of its batch: higher wins, same place (equal) none."""
    placements = session.store.rows("placements")
    stored = {(c.source, c.winner, c.loser) for c in session.store.rows("comparisons")}
    expected = set()
    for p in placements:
        for q in placements:
            if q.batch == p.batch and q.interaction < p.interaction and \
                    session.slots[q.interaction - 1].phase == session.slots[p.interaction - 1].phase:
                if p.position > q.position:
                    expected.add((p.interaction, p.interaction, q.interaction))
                elif p.position < q.position:
                    expected.add((p.interaction, q.interaction, p.interaction))
    assert len(placements) == 25 and stored == expected
    assert any(p.equal_to is not None for p in placements)  # the participant used "equal"


def test_theta_origins_follow_the_batch_plan(session):
    trials = {t.interaction: t for t in session.store.rows("trials") if t.outcome == "completed"}
    thetas = {i: (t.theta_a, t.theta_delta, t.theta_k) for i, t in trials.items()}
    assert {trials[i].origin for i in range(1, 6)} == {"sobol"}
    for batch in range(4):
        first = 6 + 5 * batch
        assert trials[first].origin == "best"
        assert thetas[first] in [thetas[i] for i in range(1, first)]  # θ* was observed before
        assert {trials[i].origin for i in range(first + 1, first + 5)} == {"learned"}
    final = session.store.rows("learner_snapshots")[-1]
    star = (final.theta_star_a, final.theta_star_delta, final.theta_star_k)
    assert trials[26].origin == "best" and thetas[26] == star
    for pair in range(4):
        a, b = trials[27 + 2 * pair], trials[28 + 2 * pair]
        assert {a.origin, b.origin} == {"best", "sobol"}
        assert star in (thetas[a.interaction], thetas[b.interaction])


def test_validation_ratings_and_questionnaire(session):
    ratings = session.store.rows("validation_ratings")
    trials = {t.trial_index: t for t in session.store.rows("trials")}
    assert len(ratings) == 4
    for rating in ratings:
        learned_second = trials[rating.trial_index].origin == "best"
        if rating.rating == "equal":
            assert rating.learned_preferred is None
        else:
            assert rating.learned_preferred == ((rating.rating == "better") == learned_second)
    answers = {a.question: a.value for a in session.store.rows("answers")}
    assert set(answers) == {"Q1", "Q2", "Q3"}
    assert answers["Q2"] in question("Q2").answers
    assert 1 <= int(answers["Q1"]) <= 5 and 1 <= int(answers["Q3"]) <= 5


def test_the_event_log_alone_rebuilds_the_state(session):
    rebuilt = replay(session.slots, session.store.events())
    assert rebuilt.model_dump() == session.state.model_dump()


def test_stored_samples_reproduce_each_trials_arrival_times(session):
    goal = np.array(session.config.controller.scene.handover_point)
    tolerance = session.config.controller.loop.robot_arrival_tolerance_m
    for trial in session.store.rows("trials")[::5]:
        rows = session.store.samples(trial.trial_index)
        t = np.array([r["t"] for r in rows])
        measured = np.array([[r["measured_x"], r["measured_y"], r["measured_z"]] for r in rows])
        inside = np.linalg.norm(measured - goal, axis=1) < tolerance
        assert t[np.argmax(inside)] == pytest.approx(trial.robot_arrival_s)
