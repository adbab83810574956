"""Coactive hints in the session (``[protocol] coactive``): after each placement of the initial and
learning batches the session waits for a hint; each is stored as its own event and row with its
provenance, reaches the learner as θ' ≻ θ, is exported, and a resumed session learns from it
exactly as one that never stopped."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from support.engine import drive_until, study_config

from app.analysis.report import build_report
from app.learning.coactive import hint_id
from app.learning.config import LearnerSnapshot
from app.protocol.doctor import examine
from app.protocol.engine import SessionEngine
from app.protocol.errors import RefusedAction
from app.protocol.hints import DIRECTIONS
from app.protocol.simulated_participant import SimulatedParticipant, Taste
from app.protocol.state import Step
from app.session.config import load_lab_config
from robot_io.config import ControllerConfig
from robot_io.control.trial import simulate_trial
from robot_io.hands.simulated_hand import Scenario
from robot_io.theta import Theta
from session_store.export import export_study
from session_store.vocabulary import Hint, Phase, Rater

#: initial 4, one learning batch of 4, the best, one validation pair: 10 interactions
SMALL = {"initial_trials": 4, "batch_size": 4, "learning_batches": 1, "best_trials": 1,
         "validation_batches": 1, "coactive": True}
#: likes the robot 0.2 s after the hand, and says so when it misses by more than 0.05 s
PICKY = Taste(preferred_gap_s=0.2, noise_s=0.01, tie_s=0.001, hint_s=0.05)


@pytest.fixture(scope="module")
def hinted(tmp_path_factory):
    study = tmp_path_factory.mktemp("study")
    engine = SessionEngine.create(study, "H01", study_config(3, **SMALL))
    drive_until(engine, Step.DONE, SimulatedParticipant(3, PICKY), max_actions=400)
    yield engine
    engine.close()


def test_every_placement_is_followed_by_a_hint_stored_with_its_provenance(hinted):
    """The module's first test builds its session (``hinted``): the small coactive protocol run
    to its end through the real learner, 10-22 s on a loaded machine."""
    placements = hinted.store.rows("placements")
    hints = hinted.store.rows("hints")
    assert [h.interaction for h in hints] == [p.interaction for p in placements] == list(range(1, 9))
    assert {h.actor for h in hints} == {Rater.SIMULATED_PARTICIPANT}
    given = [h for h in hints if h.hint is not None]
    assert given and {h.hint for h in given} <= {Hint.SOONER, Hint.LATER}
    kinds = [e.kind for e in hinted.store.events()]
    assert kinds.count("hint_given") == 8
    # each hint follows its placement at once
    assert all(kinds[i + 1] == "hint_given" for i, k in enumerate(kinds) if k == "placement_made")
    trials = {t.interaction: t for t in hinted.store.rows("trials") if t.outcome == "completed"}
    for h in given:
        theta = trials[h.interaction].theta.model_dump()
        direction = DIRECTIONS[h.hint]
        moved = {"a": h.hinted_a, "delta": h.hinted_delta, "k": h.hinted_k}
        low, high = hinted.config.theta_bounds[direction.parameter]
        expected = np.clip(theta[direction.parameter] + direction.sign * 0.2 * (high - low),
                           low, high)
        assert moved == pytest.approx({**theta, direction.parameter: expected})


def test_the_learner_holds_each_hint_as_a_point_never_run_preferred_to_its_handover(hinted):
    snapshot = LearnerSnapshot.model_validate_json(hinted.store.rows("learner_snapshots")[-1].state)
    unshown = {i.interaction_id: i.theta for i in snapshot.interactions if not i.shown}
    given = [h for h in hinted.store.rows("hints") if h.hinted_a is not None]
    assert unshown == {hint_id(str(h.interaction)): pytest.approx(
        {"a": h.hinted_a, "delta": h.hinted_delta, "k": h.hinted_k}) for h in given}
    pairs = {(c.winner, c.loser) for c in snapshot.comparisons}
    assert {(hint_id(str(h.interaction)), str(h.interaction)) for h in given} <= pairs
    # the hints took no interaction of the protocol: 8 placed, the best, a validation pair
    completed = [t for t in hinted.store.rows("trials") if t.outcome == "completed"]
    assert len(completed) == 11 and sum(t.phase == Phase.VALIDATION for t in completed) == 2


def test_the_doctor_and_the_export_agree_with_the_log(hinted, tmp_path):
    assert examine(hinted.store.path).ok
    export_study(hinted.store.path.parent, tmp_path / "export")
    table = pd.read_csv(tmp_path / "export" / "hints.csv")
    assert list(table["interaction"]) == list(range(1, 9))
    assert set(table["actor"]) == {"simulated_participant"}
    assert table["hint"].isna().sum() == sum(h.hint is None for h in hinted.store.rows("hints"))


def test_a_session_resumed_before_its_hint_learns_what_an_uninterrupted_one_does(tmp_path):
    """Slow: two sessions driven to interaction 7, each trial simulated and each θ planned by the
    preference learner (BoTorch fits of its GP)."""
    def learned(study, stop_at_hint: bool) -> tuple[list[Theta], list]:
        engine = SessionEngine.create(study, "R01", study_config(5, **SMALL))
        participant = SimulatedParticipant(5, PICKY)
        while engine.state.step is not Step.HINT or engine.state.slot.interaction < 4:
            drive_until(engine, Step.PLACE, participant)
            drive_until(engine, Step.HINT, participant)
        if stop_at_hint:  # interaction 4 is placed; its hint is not given yet
            engine.close()
            engine = SessionEngine.resume(study, "R01")
        while engine.state.step is not Step.READY or engine.state.slot.interaction < 6:
            drive_until(engine, Step.PLAN, participant)
            drive_until(engine, Step.READY, participant)
        hints = engine.store.rows("hints")
        assert hints[3].hint is not None, "the participant gave no hint about interaction 4"
        snapshot = LearnerSnapshot.model_validate_json(
            engine.store.rows("learner_snapshots")[-1].state)
        thetas = [engine.state.planned[i].theta for i in (5, 6)]
        engine.close()
        return thetas, snapshot.interactions

    assert learned(tmp_path / "a", True) == learned(tmp_path / "b", False)


def test_a_hint_out_of_turn_is_refused_and_one_for_the_participant_is_the_experimenters(tmp_path):
    engine = SessionEngine.create(tmp_path, "E01", study_config(6, **SMALL))
    try:
        with pytest.raises(RefusedAction, match="waits for 'plan', not 'hint'"):
            engine.hint(Hint.SOONER)
        drive_until(engine, Step.HINT, SimulatedParticipant(6, PICKY))
        delta = engine.state.planned[engine.state.slot.interaction].theta.delta
        row = engine.hint(Hint.LATER, by=Rater.EXPERIMENTER)
        assert row.hinted_delta == pytest.approx(min(delta + 0.4, 1.0))  # 0.2 of [−1, 1]
        assert engine.state.step is Step.PLAN and row.actor is Rater.EXPERIMENTER
        with pytest.raises(RefusedAction, match="waits for 'plan', not 'hint'"):
            engine.hint(None)
    finally:
        engine.close()


def test_later_means_a_larger_delta_in_the_controller(tmp_path):
    """app.protocol.hints: a larger δ makes the robot arrive later against the hand (eq. 10), in
    both scenarios of the simulated hand (4 hands each)."""
    config = ControllerConfig()
    for scenario in Scenario:
        gaps = {delta: np.mean([simulate_trial(config, Theta(a=5.0, delta=delta, k=5.0), scenario,
                                               seed).summary.arrival_gap_s for seed in range(4)])
                for delta in (-0.4, 0.4)}
        assert gaps[0.4] > gaps[-0.4] + 0.2, (scenario, gaps)


def test_the_lab_file_sets_coactive_hints_and_refuses_a_step_out_of_range(tmp_path):
    path = tmp_path / "lab.toml"
    path.write_text("[protocol]\ncoactive = true\nhint_step = 0.1\n")
    study = load_lab_config(path).study_config(Scenario.PERTURBED, seed=9)
    assert study.coactive and study.hint_step == 0.1
    path.write_text("[protocol]\nhint_step = 0.9\n")
    with pytest.raises(ValueError, match=r"protocol\.hint_step"):
        load_lab_config(path)


def test_the_report_counts_each_participants_hints(hinted, tmp_path):
    report = build_report(hinted.store.path.parent, tmp_path / "report", include_simulated=True)
    row = pd.read_csv(report.tables["learning"]).iloc[0]
    given = sum(h.hint is not None for h in hinted.store.rows("hints"))
    assert (row["hints_given"], row["hints_asked"]) == (given, 8) and given > 0
    assert "Hints given" in report.html.read_text()
