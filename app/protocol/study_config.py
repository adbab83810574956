"""One participant's session plan (:class:`StudyConfig`): the paper's protocol by default (Sect. V-C),
the θ box of Table I, the controller, the scenario and the seed."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from app.learning.config import (
    AcquisitionName,
    GainRule,
    SessionAcquisition,
    StoppingRule,
    epsilon_for,
)
from app.learning.models import RecommendationName
from app.protocol.design import Assignment
from app.protocol.seeds import Seed
from robot_io.config import ControllerConfig
from robot_io.hands.simulated_hand import Scenario
from robot_io.theta import THETA_BOUNDS

#: The short session's stopping rule ([protocol] preset = "short"): learning stops after a learning
#: batch once the learner thinks it more likely than not (50 %) that no handover would be preferred to
#: θ* more than 80 % of the time. Chosen among both rule families on a development study (N = 50,
#: seed 4646) and measured on fresh participants at N = 200 (docs/learning.md, "Shorter sessions").
SHORT_RULE = StoppingRule(threshold=0.5, min_batches=1, epsilon=epsilon_for(0.8))
#: The keys each ``[protocol] preset`` sets (a lab's own keys in the same table override them):
#: "paper" is the paper's protocol, "short" adds coactive hints and :data:`SHORT_RULE`.
PRESETS: dict[str, dict[str, bool | float | int]] = {
    "paper": {},
    "short": {"coactive": True, "stop_when_settled": True, "settled_threshold": 0.5,
              "settled_min_batches": 1, "settled_preference": 0.8},
}


class StudyConfig(BaseModel):
    """One participant's session plan: the paper's protocol by default (Sect. V-C)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    scenario: Scenario
    seed: Seed
    initial_trials: int = Field(5, ge=2, le=50, description="random interactions (paper: 5)")
    batch_size: int = Field(5, ge=2, le=10, description="q, interactions per learning batch (paper: 5)")
    learning_batches: int = Field(4, ge=0, le=50, description="learning batches (paper: 4)")
    best_trials: int = Field(1, ge=0, le=5, description="interactions with θ* after learning (paper: 1)")
    validation_batches: int = Field(4, ge=0, le=20, description="validation pairs (paper: 4)")
    acquisition: SessionAcquisition = Field(AcquisitionName.QNEI, description="paper: qNEI")
    recommendation: RecommendationName = Field(
        RecommendationName.POSTERIOR_MEAN, description="how the learned best θ* is recommended "
        "(best interaction, validation): the posterior-mean maximiser over the box, chosen by the "
        "recommendation study of docs/learning.md (the paper's is in_sample_mean)")
    population_prior: bool = Field(
        False, description="opt-in: the GP's prior mean is the pooled posterior mean of the "
        "completed participants of the same scenario (and θ box) in the study folder")
    prior_weight: float = Field(0.3, ge=0.0, le=10.0,
                                description="w, the weight of that prior mean (population_prior); "
                                "0.3 beat 1.0 with and without shared structure in the prior "
                                "study of docs/learning.md")
    batch_position_noise: bool = Field(
        False, description="opt-in: the learner weighs each comparison by the noise of eq. (16), "
        "a comparison between batch positions i and j √((i² + j²)/2) times as noisy as one "
        "between two first positions (docs/learning.md)")
    ties: Literal["drop", "model"] = Field(
        "drop", description="an \"equal\" placement: dropped (the paper's rule) or, \"model\", "
        "in the learner's likelihood as a tie (Davidson's tie model in probit form, "
        "docs/learning.md)")
    stop_when_settled: bool = Field(
        False, description="opt-in: end learning after a batch once the learner is "
        "settled_threshold sure that the participant's best handover would be preferred to θ* at "
        "most settled_preference of the time (and at least settled_min_batches learning batches "
        "ran); the best interaction, the questionnaire and validation follow as usual "
        "(docs/learning.md)")
    settled_threshold: float = Field(0.9, ge=0.5, le=1.0, description="the probability that "
                                     "stops learning (stop_when_settled)")
    settled_min_batches: int = Field(2, ge=1, le=50, description="learning batches run before "
                                     "learning may stop (stop_when_settled)")
    settled_preference: float = Field(0.6, gt=0.5, lt=1.0, description="θ* is settled when the "
                                      "best handover would be preferred to it at most this often "
                                      "(stop_when_settled)")
    stop_when_no_gain: bool = Field(
        False, description="opt-in: end learning after a batch once the next batch is at most "
        "gain_chance likely to show a handover preferred to θ* more than gain_preference of the "
        "time (what the next batch is expected to gain over θ*, and at least gain_min_batches "
        "learning batches ran); the best interaction, the questionnaire and validation follow as "
        "usual (docs/learning.md)")
    gain_chance: float = Field(0.2, gt=0.0, lt=1.0, description="\"unlikely\": learning stops "
                               "once the next batch's chance is at most this (stop_when_no_gain)")
    gain_preference: float = Field(0.6, gt=0.5, lt=1.0, description="a handover worth another "
                                   "batch is preferred to θ* more than this share of the time "
                                   "(stop_when_no_gain)")
    gain_min_batches: int = Field(1, ge=1, le=50, description="learning batches run before "
                                  "learning may stop (stop_when_no_gain)")
    coactive: bool = Field(
        False, description="opt-in: after placing a handover of the initial and learning batches "
        "the participant may say which way the robot should change (sooner, later, react more, "
        "react less) or that nothing should; each hint is a comparison of θ moved that way over "
        "the handover's θ (Tucker et al.'s coactive feedback, docs/learning.md)")
    hint_step: float = Field(0.2, gt=0.0, le=0.5, description="how far a coactive hint moves θ: a "
                             "share of the parameter's range (coactive)")
    preset: Literal["paper", "short"] = Field(
        "paper", description="the [protocol] preset the session was planned with: paper (the "
        "paper's protocol) or short (coactive hints and the short session's stopping rule); the "
        "keys it set are recorded as themselves")
    prior_sources: list[str] = Field(
        default_factory=list, description="the participants whose data formed the prior, fixed "
        "when the session was created (empty: no prior)")
    assignment: Assignment | None = Field(
        None, description="what the study plan ([study]) proposed for this participant, recorded "
        "when it was created (None: no plan; the scenario was chosen by hand)")
    theta_bounds: dict[str, tuple[float, float]] = Field(
        default_factory=lambda: dict(THETA_BOUNDS), description="Θ of Table I")
    controller: ControllerConfig = ControllerConfig()

    @field_validator("theta_bounds")
    @classmethod
    def _bounds_within_table_i(cls, bounds: dict[str, tuple[float, float]]) -> dict:
        if set(bounds) != set(THETA_BOUNDS):
            raise ValueError(f"theta_bounds must name {sorted(THETA_BOUNDS)}, not {sorted(bounds)}")
        for name, (low, high) in bounds.items():
            safe_low, safe_high = THETA_BOUNDS[name]
            if not safe_low <= low < high <= safe_high:
                raise ValueError(f"theta_bounds.{name} = [{low}, {high}] must lie within the safe "
                                 f"range [{safe_low}, {safe_high}] with low < high")
        return bounds

    @model_validator(mode="after")
    def _one_stopping_rule(self) -> StudyConfig:
        if self.stop_when_settled and self.stop_when_no_gain:
            raise ValueError("stop_when_settled and stop_when_no_gain are both true: learning "
                             "stops by one rule; set one of them to false")
        return self

    def stopping_rule(self) -> StoppingRule | GainRule | None:
        """When learning stops early; None: the paper's fixed schedule."""
        if self.stop_when_no_gain:
            return GainRule(chance=self.gain_chance, preference=self.gain_preference,
                            min_batches=self.gain_min_batches)
        if not self.stop_when_settled:
            return None
        return StoppingRule(threshold=self.settled_threshold,
                            min_batches=self.settled_min_batches, epsilon=self.settled_epsilon)

    @property
    def settled_epsilon(self) -> float:
        """ε of the stopping signal: the regret whose probit is ``settled_preference``,
        √2·Φ⁻¹(p) (app.learning.config.epsilon_for)."""
        return epsilon_for(self.settled_preference)

    @property
    def interactions(self) -> int:
        """Completed interactions of a full session: 5 + 20 + 1 + 8 = 34 with the defaults."""
        return (self.initial_trials + self.batch_size * self.learning_batches + self.best_trials
                + 2 * self.validation_batches)
