"""What a session's configuration derives before any handover: the learner's configuration, the
simulated hand's seed of each interaction, the Sobol references of the validation pairs."""

from __future__ import annotations

import numpy as np

from app.learning.config import LearnerConfig, ModelConfig
from app.learning.models import ParameterBox, RecommendationName, TieHandling
from app.learning.planner import BatchSchedule
from app.learning.prior import PopulationPrior
from app.protocol.study_config import StudyConfig
from robot_io.theta import Theta


def learner_config(config: StudyConfig, prior: PopulationPrior | None = None) -> LearnerConfig:
    """The learner of ``config``: its schedule for the initial and learning phases, acquisition,
    recommendation strategy and ``prior`` (the session's, from earlier participants)."""
    unique = config.initial_trials + config.learning_batches * (config.batch_size - 1)
    return LearnerConfig(box=ParameterBox.from_bounds(config.theta_bounds),
                         acquisition=config.acquisition, seed=config.seed,
                         recommendation=RecommendationName(config.recommendation), prior=prior,
                         model=ModelConfig(batch_position_noise=config.batch_position_noise,
                                           ties=TieHandling(config.ties)),
                         settled_epsilon=config.settled_epsilon,
                         expected_gain=config.stop_when_no_gain,
                         schedule=BatchSchedule(n_initial=config.initial_trials,
                                                q=config.batch_size, n_unique=unique))


def hand_seed(config: StudyConfig, interaction: int) -> int:
    """The simulated hand of an interaction: the same for every attempt at it."""
    return int(np.random.default_rng([config.seed, interaction, 0x4A4D]).integers(2**31))


def validation_sobol(config: StudyConfig) -> list[Theta]:
    """The Sobol reference points of the validation pairs, in the θ box (seeded, not the learner's)."""
    from scipy.stats import qmc  # here: scipy.stats costs every start of a session ~1 s of CPU

    engine = qmc.Sobol(3, scramble=True, seed=np.random.default_rng([config.seed, 0x50B0]))
    unit = engine.random(max(config.validation_batches, 1))
    low = np.array([b[0] for b in config.theta_bounds.values()])
    high = np.array([b[1] for b in config.theta_bounds.values()])
    return [Theta(**dict(zip(config.theta_bounds, low + u * (high - low), strict=True)))
            for u in unit[: config.validation_batches]]
