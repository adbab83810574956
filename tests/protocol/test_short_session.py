"""Issue 46 in the session: learning that stops once the next batch is unlikely to find a better
handover (``[protocol] stop_when_no_gain``, and ``preset = "short"`` that sets it with hints):
every batch's signal recorded (``learning_checked``), the stop with its reason, the dashboard's
words, the report's row; a rule that never fires checks every batch and runs the schedule."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from support.engine import SESSION_LOOP_TOML, drive_until, protocol_toml, study_config

from app.analysis.report import build_report
from app.cli import main
from app.learning.config import GainRule
from app.protocol import stopping
from app.protocol.engine import SessionEngine
from app.protocol.learning_words import learning_line, recorded_stop
from app.protocol.simulated_participant import SimulatedParticipant, Taste
from app.protocol.state import Step, replay
from app.protocol.study_config import PRESETS, SHORT_RULE
from app.session.config import load_lab_config
from robot_io.hands.simulated_hand import Scenario
from session_store.vocabulary import Phase

#: Likes the robot 0.1 s after the hand, feels it precisely and says so when it misses by 0.05 s.
EASY = Taste(preferred_gap_s=0.1, noise_s=0.005, tie_s=0.001, hint_s=0.05)
#: A rule loose enough to stop this participant after its first learning batch: "the next batch is
#: at most 95 % likely to find a handover preferred to θ* more than 95 % of the time".
LOOSE = {"coactive": True, "stop_when_no_gain": True, "gain_chance": 0.95,
         "gain_preference": 0.95, "gain_min_batches": 1}
#: 4 initial, up to 3 learning batches of 4, the best, 2 validation pairs.
SMALL = {"initial_trials": 4, "batch_size": 4, "learning_batches": 3, "best_trials": 1,
         "validation_batches": 2}


@pytest.fixture(scope="module")
def stopped(tmp_path_factory):
    engine = SessionEngine.create(tmp_path_factory.mktemp("study"), "P01",
                                  study_config(2, Scenario.STRAIGHTFORWARD, **SMALL, **LOOSE))
    drive_until(engine, Step.DONE, SimulatedParticipant(2, EASY), max_actions=600)
    yield engine
    engine.close()


def kinds(engine: SessionEngine, kind: str) -> list[dict]:
    return [e.payload for e in engine.store.events() if e.kind == kind]


def dashboard_line(engine: SessionEngine) -> str | None:
    """The dashboard's learning line of ``engine``, as the runner's view makes it."""
    return learning_line(engine.state, engine.config, engine.settledness,
                         recorded_stop(engine.store.events()),
                         engine.store.rows("learner_snapshots", order_by="after_interaction"),
                         engine.gain)


def test_every_batch_is_checked_and_learning_stops_with_its_reason(stopped):
    """Slow where it runs first: the module's ``stopped`` session is driven to its end here
    through the engine and its real learner (fits, searches and the gain check of each batch)."""
    checks, stops = kinds(stopped, "learning_checked"), kinds(stopped, "learning_stopped")
    assert len(stops) == 1
    stop = stops[0]
    # a check after the initial batch (0 learning batches: no stop yet) and after each learning
    # batch up to the one that stopped
    assert [c["batches"] for c in checks] == list(range(stop["batches"] + 1))
    assert [c["after_interaction"] for c in checks] == [4 + 4 * b for b in range(len(checks))]
    assert all(c["rule"] == "gain" and 0 <= c["signal"] <= 1 and c["gain"] >= 0 for c in checks)
    assert [c["stops"] for c in checks] == [False] * (len(checks) - 1) + [True]
    assert stop["rule"] == "gain" and stop["probability"] == checks[-1]["signal"] <= 0.95
    assert stop["threshold"] == 0.95 and stop["after_interaction"] == checks[-1]["after_interaction"]
    assert stop["reason"].startswith(f"after learning batch {stop['batches']} of 3 the next batch "
                                     "was at most ")
    assert stop["reason"].endswith("likely to find a handover the participant would pick over the "
                                   "learner's best guess more than 95 % of the time; it stops at "
                                   "95 % or less, from batch 1 on")
    # the signal is the bound (q − 1)·g/ε of what the next batch may find
    rule = stopped.config.stopping_rule()
    assert isinstance(rule, GainRule)
    assert checks[-1]["signal"] == pytest.approx(min(1.0, 3 * checks[-1]["gain"] / rule.epsilon))
    learned = [t for t in stopped.store.rows("trials") if t.outcome == "completed"
               and t.phase in (Phase.INITIAL, Phase.LEARNING)]
    assert len(learned) == stop["after_interaction"] < 16
    assert len(stopped.store.rows("hints")) == len(learned)  # hints on every placement


def test_after_the_stop_the_best_the_questionnaire_and_validation_run(stopped):
    completed = [t for t in stopped.store.rows("trials") if t.outcome == "completed"]
    assert sum(t.phase == Phase.BEST for t in completed) == 1
    assert sum(t.phase == Phase.VALIDATION for t in completed) == 4
    assert set(stopped.state.answers) == {"Q1", "Q2", "Q3"} and stopped.state.step is Step.DONE
    state = replay(stopped.slots, stopped.store.events())  # the checks replay with the stop
    assert state.stopped_after == stopped.state.stopped_after and state.step is Step.DONE


def test_the_dashboard_and_the_report_say_why_learning_stopped(stopped, tmp_path):
    line = dashboard_line(stopped)
    batch = stopped.state.slots[stopped.state.stopped_after - 1].batch
    assert line.startswith(f"Learning stopped early after batch {batch} of 3: ")
    assert line.endswith(f"({kinds(stopped, 'learning_stopped')[0]['reason']}).")
    report = build_report(stopped.store.path.parent, tmp_path / "report", include_simulated=True)
    row = pd.read_csv(report.tables["learning"]).iloc[0]
    assert row["learning_ended"] == "early" and row["why"].startswith("after learning batch ")
    assert row["stopping_rule"] == ("stop once the next batch is at most 95 % likely to find a "
                                    "handover the participant would pick over the learner's best "
                                    "guess more than 95 % of the time, from batch 1 on")
    assert row["learning_interactions"] == stopped.state.stopped_after


def test_a_rule_that_never_fires_checks_every_batch_and_runs_the_schedule(tmp_path):
    """Slow: a session through the engine and its real learner up to the questionnaire (a fit
    after each placement and hint, a search for each batch, the gain check after each batch)."""
    strict = {**LOOSE, "gain_chance": 0.001, "gain_preference": 0.55}
    engine = SessionEngine.create(tmp_path, "P02", study_config(
        4, Scenario.PERTURBED, **{**SMALL, "learning_batches": 1, "validation_batches": 1},
        **strict))
    try:
        drive_until(engine, Step.ANSWER, SimulatedParticipant(4, EASY), max_actions=300)
        checks = kinds(engine, "learning_checked")
        # after the initial batch, and after the last learning batch (which stops nothing)
        assert [(c["batches"], c["after_interaction"], c["stops"]) for c in checks] == [
            (0, 4, False), (1, 8, False)]
        assert not kinds(engine, "learning_stopped")
        line = dashboard_line(engine)
        assert line is not None and line.startswith("After learning batch 1 of 1: ")
        assert "; the next batch is at most " in line
        assert line.endswith("more than 55 % of the time. That was the last learning batch.")
    finally:
        engine.close()


def test_the_paper_protocol_checks_nothing():
    config = study_config(1)
    assert config.stopping_rule() is None and config.preset == "paper"
    assert stopping.check(config, 10, 1, None, None) == []


def test_the_short_preset_sets_hints_and_the_rule_and_a_lab_key_wins(tmp_path):
    path = tmp_path / "lab.toml"
    path.write_text('[protocol]\npreset = "short"\n')
    study = load_lab_config(path).study_config(Scenario.PERTURBED, seed=9)
    assert study.preset == "short" and study.coactive and study.stop_when_settled
    assert study.stopping_rule() == SHORT_RULE
    assert {k: getattr(study, k) for k in PRESETS["short"]} == PRESETS["short"]
    path.write_text('[protocol]\npreset = "short"\nsettled_threshold = 0.9\n')
    assert load_lab_config(path).study_config(Scenario.PERTURBED, seed=9).settled_threshold == 0.9
    path.write_text('[protocol]\npreset = "short"\nstop_when_no_gain = true\n')
    with pytest.raises(ValueError, match='preset = "short" sets it'):
        load_lab_config(path)
    path.write_text('[protocol]\npreset = "quick"\n')
    with pytest.raises(ValueError, match=r"protocol\.preset"):
        load_lab_config(path)
    path.write_text('[protocol]\ngain_preference = 1.0\n')
    with pytest.raises(ValueError, match=r"protocol\.gain_preference"):
        load_lab_config(path)


def test_run_session_says_where_learning_stopped_and_why(tmp_path, capsys):
    """The headless command with a lab file that stops early: its summary says after how many
    interactions learning stopped and why. A whole session with its learner and rig processes:
    20-60 s."""
    lab = tmp_path / "lab.toml"
    lab.write_text(SESSION_LOOP_TOML + "[protocol]\n" + protocol_toml({**SMALL, **LOOSE}))
    assert main(["run-session", "--study", str(tmp_path / "study"), "--participant", "S01",
                 "--scenario", "straightforward", "--auto", "--seed", "2", "--config", str(lab),
                 "--json", "--no-progress"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    learning = summary["learning"]
    assert learning["interactions"] < 16 and learning["stopped_early"].startswith("after ")
    assert summary["counts"]["hints"] == learning["interactions"]
