"""``handover replay-stop`` (app.analysis.stop_replay): a stopping rule replayed on stored sessions
stops where the same rule stopped a live session, with the same θ* and signal."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.stats import norm
from support.engine import drive_until, study_config

from app.analysis.stop_replay import preferred, replay_study
from app.cli import main
from app.learning.config import GainRule, LearnerSnapshot
from app.learning.learner import PreferenceLearner
from app.protocol.engine import SessionEngine
from app.protocol.simulated_participant import SimulatedParticipant, Taste
from app.protocol.state import Step
from robot_io.hands.simulated_hand import Scenario
from session_store.read_only_copy import reading
from session_store.vocabulary import Phase

EASY = Taste(preferred_gap_s=0.1, noise_s=0.005, tie_s=0.001, hint_s=0.05)
SMALL = {"initial_trials": 4, "batch_size": 4, "learning_batches": 3, "best_trials": 1,
         "validation_batches": 1, "coactive": True}
RULE = GainRule(chance=0.95, preference=0.95, min_batches=1)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """The same participant (seed 2) twice: in a study whose sessions stop by :data:`RULE`, and in
    one that runs the whole schedule. Two whole sessions with their learner processes: 30-60 s."""
    live, full = tmp_path_factory.mktemp("live"), tmp_path_factory.mktemp("full")
    rule = {"stop_when_no_gain": True, "gain_chance": RULE.chance,
            "gain_preference": RULE.preference, "gain_min_batches": RULE.min_batches}
    for study, extra in ((live, rule), (full, {})):
        engine = SessionEngine.create(study, "P01",
                                      study_config(2, Scenario.STRAIGHTFORWARD, **SMALL, **extra))
        drive_until(engine, Step.DONE, SimulatedParticipant(2, EASY), max_actions=600)
        engine.close()
    return live, full


def test_the_replayed_rule_stops_where_the_live_rule_stopped(sessions):
    """The first test of the module: it waits for the two sessions of :func:`sessions` (30-60 s)."""
    live, full = sessions
    with reading(live, "P01") as store:
        stop = next(e.payload for e in store.events() if e.kind == "learning_stopped")
        best = next(t for t in store.rows("trials") if t.phase == Phase.BEST)
    (row,) = replay_study(full, [RULE])
    assert row.stopped_after == stop["after_interaction"] < row.learned == 16
    assert row.signal == pytest.approx(stop["probability"], abs=1e-9)
    assert row.theta_stop == pytest.approx({"a": best.theta_a, "delta": best.theta_delta,
                                            "k": best.theta_k})
    assert 0.0 < row.preferred_final < 1.0
    # on the session that stopped, the rule finds nothing more to stop: it keeps what ran
    (same,) = replay_study(live, [RULE])
    assert same.stopped_after == same.learned == stop["after_interaction"] and same.signal is None
    assert same.theta_stop == same.theta_final and same.preferred_final == pytest.approx(0.5)


def test_the_predicted_preference_is_the_probit_over_the_posterior(sessions):
    """P(a ≻ b) = E[Φ((u_a − u_b)/√2)] over posterior draws = Φ(m/√(2 + s²))."""
    _, full = sessions
    with reading(full, "P01") as store:
        snapshot = LearnerSnapshot.model_validate_json(store.rows("learner_snapshots")[-1].state)
    learner = PreferenceLearner.restore(snapshot)
    first, second = {"a": 2.0, "delta": 0.5, "k": 3.0}, learner.best().theta
    box = learner.config.box
    torch.manual_seed(0)
    with torch.no_grad():
        draws = learner.model.model.posterior(torch.tensor(
            [box.to_unit(first), box.to_unit(second)], dtype=torch.float64)).rsample(
            torch.Size([100_000])).reshape(-1, 2).numpy()
    expected = float(np.mean(norm.cdf((draws[:, 0] - draws[:, 1]) / np.sqrt(2.0))))
    assert preferred(learner, first, second) == pytest.approx(expected, abs=0.005)
    assert preferred(learner, second, first) == pytest.approx(1 - expected, abs=0.005)


def test_the_command_prints_each_rule_and_writes_its_rows(sessions, tmp_path, capsys):
    _, full = sessions
    out = tmp_path / "replay.csv"
    assert main(["replay-stop", str(full), "--chance", "0.01", "0.95", "--preference", "0.95",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "the next batch is at most 1 % likely" in printed and "did not stop" in printed
    assert "at most 95 % likely" in printed and "the final learner prefers its θ*" in printed
    assert len(out.read_text().splitlines()) == 3  # a header and one row per rule


@pytest.mark.parametrize("args,message", [(["--chance", "1.5"], "chance"),
                                          (["--preference", "0.5"], "preference"),
                                          (["--min-batches", "0"], "min_batches")])
def test_bad_options_name_the_field_and_its_range(tmp_path, capsys, args, message):
    with pytest.raises(SystemExit) as exit_:
        main(["replay-stop", str(tmp_path), *args])
    assert exit_.value.code == 2 and message in capsys.readouterr().err
