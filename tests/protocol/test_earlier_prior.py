"""A session's prior from earlier participants and its recommendation strategy, through the engine:
which participants feed the prior (completed, same scenario and box), that it is recorded in the
session and survives a resume, and that the configured strategy reaches the learner."""

from __future__ import annotations

from support.engine import SHORT_PROTOCOL, drive_until, study_config

from app.learning.config import LearnerSnapshot
from app.learning.learner import PreferenceLearner
from app.learning.models import RecommendationName
from app.learning.pooled_prior import population_prior
from app.protocol.engine import SessionEngine
from app.protocol.session_inputs import learner_config
from app.protocol.state import Step
from app.protocol.study_config import StudyConfig
from robot_io.hands.simulated_hand import Scenario
from session_store.store import ParticipantStore
from session_store.vocabulary import Phase


def config(seed: int, scenario: Scenario = Scenario.STRAIGHTFORWARD, **learner) -> StudyConfig:
    return study_config(seed, scenario, population_prior=True, **SHORT_PROTOCOL, **learner)


def complete(study, code: str, seed: int, scenario: Scenario = Scenario.STRAIGHTFORWARD) -> None:
    engine = SessionEngine.create(study, code, config(seed, scenario))
    try:
        drive_until(engine, Step.DONE)
    finally:
        engine.close()


def final_snapshot(study, code: str) -> LearnerSnapshot:
    store = ParticipantStore.open(study, code)
    try:
        return LearnerSnapshot.model_validate_json(store.rows("learner_snapshots")[-1].state)
    finally:
        store.close()


def test_the_prior_comes_from_completed_participants_of_the_scenario_and_is_recorded(tmp_path):
    """Slow: a prior needs completed participants: three whole sessions with the real learner (each
    batch a BoTorch fit), one half session, then the participant whose prior is checked."""
    study = tmp_path / "study"
    complete(study, "P01", seed=1)  # the first participant: nobody earlier, no prior
    complete(study, "P02", seed=2)
    complete(study, "Q01", seed=3, scenario=Scenario.PERTURBED)  # another scenario
    unfinished = SessionEngine.create(study, "P03", config(seed=4))
    drive_until(unfinished, Step.PLACE)  # in the middle of its session: not completed
    unfinished.close()

    engine = SessionEngine.create(study, "P04", config(seed=5))
    try:
        assert engine.config.prior_sources == ["P01", "P02"]
        assert engine.prior is not None and engine.prior.sources == ["P01", "P02"]
        created = engine.store.events()[0]
        assert created.kind == "session_created"
        assert created.payload["prior"]["components"][0]["source"] == "P01"
        assert engine.store.participant().config["prior_sources"] == ["P01", "P02"]
        stored_prior = engine.prior
        drive_until(engine, Step.PLACE)
    finally:
        engine.close()
    # exactly the pooled posterior mean of the completed participants' final snapshots
    finals = {code: final_snapshot(study, code) for code in ("P01", "P02")}
    assert stored_prior == population_prior(finals, weight=config(seed=5).prior_weight)
    assert stored_prior.weight == 0.3  # the default, chosen by the prior study

    resumed = SessionEngine.resume(study, "P04")
    try:
        assert resumed.prior == stored_prior  # from the file alone, not rebuilt from the folder
        assert learner_config(resumed.config, resumed.prior).prior == stored_prior
        drive_until(resumed, Step.DONE)
        snapshot = resumed.store.rows("learner_snapshots")[-1].state
        assert '"source":"P02"' in snapshot  # every stored learner snapshot carries the prior
    finally:
        resumed.close()
    later = SessionEngine.create(study, "P05", config(seed=6))
    later.close()
    assert later.config.prior_sources == ["P01", "P02", "P04"]


def test_without_the_opt_in_no_prior_is_built(tmp_path):
    study = tmp_path / "study"
    complete(study, "P01", seed=1)
    engine = SessionEngine.create(study, "P02", config(seed=2).model_copy(
        update={"population_prior": False}))
    try:
        assert engine.prior is None and engine.config.prior_sources == []
        assert learner_config(engine.config, engine.prior).prior is None
    finally:
        engine.close()


def test_the_configured_recommendation_chooses_the_best_interaction(tmp_path):
    """Slow: a whole session through the engine and its real learner (a fit after each placement,
    a search of the box for each batch and for θ*)."""
    engine = SessionEngine.create(tmp_path / "study", "P01",
                                  config(seed=3, recommendation="posterior_mean"))
    try:
        assert learner_config(engine.config).recommendation is RecommendationName.POSTERIOR_MEAN
        drive_until(engine, Step.DONE)
        best_slot = next(s for s in engine.slots if s.phase is Phase.BEST)
        after_learning = next(r for r in engine.store.rows("learner_snapshots")
                              if r.after_interaction == best_slot.interaction - 1)
        learner = PreferenceLearner.restore(LearnerSnapshot.model_validate_json(
            after_learning.state))
        best = learner.best()
        assert best.strategy is RecommendationName.POSTERIOR_MEAN
        planned = engine.state.planned[best_slot.interaction].theta.model_dump()
        assert planned == best.theta
    finally:
        engine.close()
