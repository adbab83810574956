"""Configuration records of the learner, free of torch so that callers (the session engine, the
``handover`` command) can build and validate them without importing BoTorch.
"""

from __future__ import annotations

import math
from enum import StrEnum
from statistics import NormalDist
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from app.learning.models import (
    Comparison,
    FitReport,
    Interaction,
    NextBatchGain,
    ParameterBox,
    RecommendationName,
    Settledness,
    TieHandling,
)
from app.learning.planner import BatchSchedule
from app.learning.prior import PopulationPrior

#: Serialisable kernel hyperparameters: raw parameter name → values (the warm start, the snapshot).
Hyperparameters = dict[str, list[float]]


#: ε of the stopping signal: √2·Φ⁻¹(0.6), the regret at which the best θ would be preferred to θ*
#: 60 % of the time under the probit of eq. (13) (:func:`epsilon_for`).
DEFAULT_SETTLED_EPSILON = 0.3583


def epsilon_for(preferred: float) -> float:
    """The utility difference ε at which one handover is preferred to another with probability
    ``preferred`` under the probit of eq. (13): Φ(ε/√2) = preferred."""
    return math.sqrt(2.0) * NormalDist().inv_cdf(preferred)


def preferred_for(epsilon: float) -> float:
    """The inverse of :func:`epsilon_for`: Φ(ε/√2)."""
    return NormalDist().cdf(epsilon / math.sqrt(2.0))


class AcquisitionName(StrEnum):
    """The acquisition functions the learner offers."""

    QNEI = "qnei"
    QLOGNEI = "qlognei"
    EUBO = "eubo"
    SOBOL = "sobol"

    def __repr__(self) -> str:
        """The name as a lab file writes it: a refusal lists the allowed ones so."""
        return repr(self.value)


#: The acquisitions a study session may run ([learner] acquisition): every one the learner offers
#: but Sobol, the simulated study's random search, which learns nothing.
SessionAcquisition = Literal[AcquisitionName.QNEI, AcquisitionName.QLOGNEI, AcquisitionName.EUBO]


#: The recommendation default, chosen by the recommendation study of docs/learning.md (N = 100
#: paired seeds, qNEI q = 5 and EUBO at σ = 0, 0.03, 0.05): the box maximiser of the posterior mean
#: is never worse than the in-sample argmax (σ = 0.05: +0.001 [−0.007, +0.010] and −0.004
#: [−0.009, +0.001]) and better where placements are reliable (σ = 0: −0.012 and −0.009, paired
#: CIs excluding 0; EUBO at σ = 0.03: −0.006 [−0.011, −0.002]), at one optimisation per θ*.
DEFAULT_RECOMMENDATION = RecommendationName.POSTERIOR_MEAN


class OptimizerConfig(BaseModel):
    """How hard the acquisition function is optimised (``optimize_acqf``) and sampled (MC)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    num_restarts: int = Field(4, ge=1, description="L-BFGS-B starts; BoTorch's tutorials use 10")
    raw_samples: int = Field(256, ge=1, description="quasi-random points that pick the starts")
    mc_samples: int = Field(256, ge=1, description="QMC samples of the posterior for qNEI/qLogNEI")
    tolerance: float | None = Field(
        None, gt=0.0, lt=1.0, description="L-BFGS-B relative tolerance (ftol) of the acquisition "
        "and recommendation searches; None is SciPy's default 2.2e-9")

    @property
    def scipy_options(self) -> dict[str, float | None]:
        """``optimize_acqf``'s ``options``: the tolerance, if one is set (BoTorch's batched
        L-BFGS-B takes ``ftol`` only with its default ``factr`` cleared)."""
        return {} if self.tolerance is None else {"ftol": self.tolerance, "factr": None}


class ModelConfig(BaseModel):
    """Kernel priors and fit settings of the preference GP."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    lengthscale_prior: tuple[float, float] = Field(
        (2.4, 2.7), description="Gamma(concentration, rate) on each RBF lengthscale in unit-cube "
        "units; mode 0.52, i.e. utilities vary over about half the box (BoTorch's choice)")
    outputscale_range: tuple[float, float] = Field(
        (0.01, 100.0), description="smoothed-box prior on the kernel output scale; with the probit "
        "noise fixed at 1 this bounds how sharp preferences can be")
    fit_max_attempts: int = Field(
        5, ge=1, description="fit_gpytorch_mll retries from resampled priors on optimiser warnings")
    fit_tolerance: float | None = Field(
        None, gt=0.0, description="L-BFGS-B relative tolerance (ftol) of the hyperparameter fit; "
        "None is SciPy's default 2.2e-9, far below what changes a suggestion")
    warm_start: bool = Field(True, description="start each fit from the previous hyperparameters")
    lazy_fit: bool = Field(
        False, description="after an interaction only recompute the posterior with the current "
        "hyperparameters; fit them before the next acquisition query instead")
    lazy_kernels: bool = Field(
        False, description="evaluate kernels through GPyTorch's lazy kernel tensors (GPyTorch's "
        "default, what BoTorch's tutorials run); off: kernel matrices are computed directly, the "
        "same numbers with less overhead at the few dozen points of a session")
    batch_position_noise: bool = Field(
        False, description="weigh each comparison by the noise of eq. (16): a comparison between "
        "batch positions i and j is √((i² + j²)/2) times as noisy as one between two first "
        "positions (app.learning.comparison_noise); off: every comparison equally reliable, as "
        "BoTorch's probit likelihood has it")
    ties: TieHandling = Field(
        TieHandling.DROP, description="an \"equal\" placement: dropped (the paper's rule) or, "
        "\"model\", in the likelihood as two half-weighted opposite comparisons (Davidson's tie "
        "model in probit form, app.learning.ties)")
    refit_growth: float = Field(
        0.0, ge=0.0, description="refit the hyperparameters only once the number of comparisons "
        "has grown by this fraction since the last fit (0: whenever new comparisons arrived); "
        "in between, the posterior is recomputed with the current hyperparameters")


class StoppingRule(BaseModel):
    """When learning stops early (``[protocol] stop_when_settled``): after a learning batch, once at
    least ``min_batches`` learning batches are done and the stopping signal
    (:class:`~app.learning.models.Settledness`) has reached ``threshold``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    threshold: float = Field(0.9, ge=0.5, le=1.0, description="the signal's probability that "
                             "stops learning")
    min_batches: int = Field(2, ge=1, le=50, description="learning batches run before any stop")
    epsilon: float = Field(DEFAULT_SETTLED_EPSILON, gt=0.0, le=5.0,
                           description="ε of the signal: θ*'s regret in latent utility")

    def stops(self, batches_done: int, signal: Settledness | None) -> bool:
        """Whether learning stops after ``batches_done`` learning batches at this signal."""
        return (batches_done >= self.min_batches and signal is not None
                and signal.probability_within(self.epsilon) >= self.threshold)


class GainRule(BaseModel):
    """When learning stops early by what the next batch is expected to gain
    (``[protocol] stop_when_no_gain``, :mod:`app.learning.gain`): after a learning batch, once at
    least ``min_batches`` learning batches are done and the next batch is less than ``chance``
    likely to show a handover preferred to θ* more than ``preference`` of the time (the bound
    (q − 1)·g/ε of :meth:`~app.learning.models.NextBatchGain.chance`)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    chance: float = Field(0.2, gt=0.0, lt=1.0, description="\"unlikely\": learning stops once "
                          "the next batch's chance is at most this")
    preference: float = Field(0.6, gt=0.5, lt=1.0, description="a handover worth finding is "
                              "preferred to θ* more than this share of the time")
    min_batches: int = Field(1, ge=1, le=50, description="learning batches run before any stop")

    @property
    def epsilon(self) -> float:
        """ε of :attr:`preference` (:func:`epsilon_for`), latent utility."""
        return epsilon_for(self.preference)

    def stops(self, batches_done: int, gain: NextBatchGain | None) -> bool:
        """Whether learning stops after ``batches_done`` learning batches at this gain."""
        return (batches_done >= self.min_batches and gain is not None
                and gain.chance(self.epsilon) <= self.chance)


class LearnerConfig(BaseModel):
    """Everything that defines a learner's behaviour; stored with every snapshot."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    box: ParameterBox
    acquisition: AcquisitionName = AcquisitionName.QNEI
    schedule: BatchSchedule = BatchSchedule()
    model: ModelConfig = ModelConfig()
    optimizer: OptimizerConfig = OptimizerConfig()
    recommendation: RecommendationName = Field(
        DEFAULT_RECOMMENDATION, description="how θ* is recommended (docs/learning.md, "
        "recommendation study); the batch-opening θ* is the in-sample incumbent whatever this is")
    lcb_beta: float = Field(1.0, ge=0.0, le=10.0,
                            description="β of the in-sample lower confidence bound mean − β·std")
    settled_epsilon: float = Field(
        DEFAULT_SETTLED_EPSILON, gt=0.0, le=5.0, description="ε of the stopping signal: θ* is "
        "settled when its regret (latent utility) is at most ε; the default 0.358 means the best "
        "θ would be preferred to θ* at most 60 % of the time (app.learning.settled)")
    expected_gain: bool = Field(
        False, description="after each batch, also compute what the next batch is expected to "
        "gain over θ* (app.learning.gain), the signal of [protocol] stop_when_no_gain; off: not "
        "computed (it costs one optimisation per batch)")
    prior: PopulationPrior | None = Field(
        None, description="prior mean from earlier participants (app.learning.population); "
        "None: the zero mean of eq. (12)")
    seed: int = 0


class LearnerSnapshot(BaseModel):
    """A learner's complete state as plain data: config, observations (in the order they arrived),
    fitted hyperparameters, and the report of its last fit (what its next suggestion carries)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    config: LearnerConfig
    interactions: list[Interaction]
    comparisons: list[Comparison]
    hyperparameters: Hyperparameters | None = None
    fitted_comparisons: int = Field(0, ge=0, description="comparisons at the last hyperparameter fit")
    last_fit: FitReport | None = Field(
        None, description="report of the last fit (None in snapshots stored before it was kept)")
