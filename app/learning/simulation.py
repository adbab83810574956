"""One trial of the simulated interaction-constrained learning task (Sect. IV).

A target θ_t is drawn uniformly in the unit cube; the simulated participant's utility is the
distance u(θ) = ‖θ_t − θ‖₂ (15) (smaller is better) and each interaction is observed as
y(θ) = u(θ) + j·N(0, σ²) (16), j = 1 … q its index within the batch, so later interactions of a
batch are remembered less reliably. The participant places each interaction on the relative
scale at a position that decreases with y (so θ_r ≻ θ_c exactly when y(θ_r) < y(θ_c)), and the
comparisons come from the same scale rule as in the human study (:mod:`app.learning.scale`): the
newest interaction against every earlier one of its batch. With a tie threshold (``tie``) the
participant places an interaction "equal" to the earlier one of its batch whose y is closest, when
closer than ``tie`` (as the session's simulated participant does within its ``tie_s``). A
coactive participant (``coactive``, :mod:`app.learning.coactive`) says after each placement which
way the handover should have moved, if any way feels better enough (:func:`participant_hint`). The
schedule is the paper's: 5 Sobol points, then batches of θ* + q − 1 queries until 25 unique points
have been shown.

Reported per interaction, after the model has been updated with that interaction's comparisons:
the *inference* distance u(θ*) of the recommended θ* to the target under every recommendation
strategy (:mod:`app.learning.recommendation`; the same search, so the strategies are compared on
identical data), and the distance of the point just shown, whose running minimum is the *oracle*
curve (the best point shown so far). Success is u(θ*) < 0.1.

Population mode (``spread``): the participants of a population share an optimum θ_0 ~ U[0, 1]^d and
each one's target is θ_0 + N(0, spread²·I), clipped to the cube; without a spread every target is
uniform (no shared structure); ``spread = "paper"``: the paper's own participants, resampled from
Tables II–III (:mod:`app.learning.paper_population`). :func:`participant_target` draws them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from app.learning.coactive import HintDirection, felt_hint, hint_observations, hinted_theta
from app.learning.config import (
    DEFAULT_RECOMMENDATION,
    AcquisitionName,
    GainRule,
    LearnerConfig,
    ModelConfig,
    OptimizerConfig,
    StoppingRule,
)
from app.learning.learner import PreferenceLearner
from app.learning.models import (
    Comparison,
    FitReport,
    Interaction,
    NextBatchGain,
    ParameterBox,
    Placement,
    RecommendationName,
    Settledness,
    SlotKind,
    TieHandling,
)
from app.learning.paper_population import PAPER_POPULATION, PaperPopulation, paper_optimum
from app.learning.planner import BatchSchedule
from app.learning.prior import PopulationPrior
from app.learning.rng import derive_seed
from app.learning.scale import comparisons_for_newest

#: u(θ*) below this counts as a success (Sect. IV).
SUCCESS_DISTANCE = 0.1

#: The coordinates of the unit cube a coactive participant hints about (0-based): the 2nd and 3rd,
#: the analogues of δ ("come sooner/later") and k ("react more/less to me"); none about the 1st,
#: the analogue of a, which has no hint on the tablet.
HINTED_COORDINATES = (1, 2)


#: The study's speed preset (see ``benchmarks/study_speed.py`` for its cost and accuracy against
#: BoTorch's tutorial defaults): hyperparameters fitted warm-started, only before a query and only
#: once the comparisons have grown by 50 %, to a relative tolerance of 1e-4; the posterior itself
#: is updated after every interaction.
STUDY_MODEL = ModelConfig(lazy_fit=True, refit_growth=0.5, fit_tolerance=1e-4)
#: Two L-BFGS-B starts picked from 128 quasi-random points, 128 QMC samples for qNEI, and searches
#: stopped once an iteration gains less than 1e-3 (relative, at least absolute 1e-3): the
#: acquisition's optimum need not be found to nine digits to pick the next handover.
STUDY_OPTIMIZER = OptimizerConfig(num_restarts=2, raw_samples=128, mc_samples=128, tolerance=1e-3)


class StudyCondition(BaseModel):
    """One condition of the simulated study: acquisition, batch size q and noise σ of eq. (16)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    acquisition: AcquisitionName = AcquisitionName.QNEI
    q: int = Field(5, ge=2, le=25, description="interactions per batch, θ* included")
    noise: float = Field(0.0, ge=0.0, le=1.0, description="σ of eq. (16)")
    n_unique: int = Field(25, ge=2, le=200, description="unique points shown (paper: 25)")
    n_initial: int = Field(5, ge=1, le=50, description="initial Sobol points (paper: 5)")
    dim: int = Field(3, ge=1, le=10, description="dimension of θ (paper: 3)")
    model: ModelConfig = Field(STUDY_MODEL, description="fit settings (study preset)")
    optimizer: OptimizerConfig = Field(STUDY_OPTIMIZER, description="acquisition optimisation")
    recommendation: RecommendationName = Field(
        DEFAULT_RECOMMENDATION, description="the strategy of the ``distance`` column (all "
        "strategies are recorded)")
    tie: float = Field(0.0, ge=0.0, le=1.0, description="the participant places an interaction "
                       "\"equal\" to an earlier one of its batch whose y is closer than this "
                       "(0: never)")
    coactive: bool = Field(False, description="after each placement the participant may give a "
                           "coactive hint (app.learning.coactive)")
    hint_step: float = Field(0.2, gt=0.0, le=1.0, description="how far a hint moves θ, as a "
                             "share of the parameter's range")
    hint_threshold: float = Field(0.05, ge=0.0, le=1.0, description="the felt gain in u a "
                                  "direction needs for a hint (the just-noticeable difference)")
    hint_flip: float = Field(0.0, ge=0.0, le=1.0, description="the share of hints that point the "
                             "opposite way to what the participant felt (wrong hints)")
    hint_faster: float = Field(0.0, ge=0.0, le=1.0, description="the share of hints for which "
                               "the participant reads \"sooner\" as \"faster\": the sooner "
                               "hint then means a faster robot (the 1st coordinate up, which has "
                               "no word), and the learner still reads it as δ down")

    @property
    def name(self) -> str:
        """Short label, e.g. ``qnei-q5-s0.05`` (``-bpn``: comparisons weighed by batch position;
        ``-tie0.05-model``: ties within 0.05, in the likelihood; ``-coactive0.2``: hints that move
        θ by 0.2 of the range; ``-flip0.3``: 30 % of them wrong; ``-faster0.5``: "sooner" read as
        "faster" half the time)."""
        return (f"{self.acquisition.value}-q{self.q}-s{self.noise:g}"
                + ("-bpn" if self.model.batch_position_noise else "")
                + (f"-tie{self.tie:g}-{self.model.ties.value}" if self.tie else "")
                + (f"-coactive{self.hint_step:g}" if self.coactive else "")
                + (f"-flip{self.hint_flip:g}" if self.coactive and self.hint_flip else "")
                + (f"-faster{self.hint_faster:g}" if self.coactive and self.hint_faster else ""))

    def with_ties(self, tie: float, handling: TieHandling) -> StudyCondition:
        """The same condition with a participant who says "equal" within ``tie``, its ties
        dropped or modelled by the learner (:mod:`app.learning.ties`)."""
        model = self.model.model_copy(update={"ties": handling})
        return self.model_copy(update={"tie": tie, "model": model})

    def with_batch_position_noise(self, on: bool) -> StudyCondition:
        """The same condition with the likelihood of :mod:`app.learning.comparison_noise` on/off."""
        model = self.model.model_copy(update={"batch_position_noise": on})
        return self.model_copy(update={"model": model})

    @property
    def schedule(self) -> BatchSchedule:
        return BatchSchedule(n_initial=self.n_initial, q=self.q, n_unique=self.n_unique)


class TrialResult(BaseModel):
    """Per-interaction distances of one trial; ``distances[i]`` is u(θ*) after interaction i."""

    model_config = ConfigDict(frozen=True, extra="forbid", ser_json_inf_nan="constants")

    trial: int
    distances: list[float] = Field(description="inference curve of the condition's strategy")
    shown_distances: list[float]
    strategy_distances: dict[RecommendationName, list[float]] = Field(
        default_factory=dict, description="inference curve of every recommendation strategy; "
        "NaN where it was not computed (only the final value of untracked strategies is)")
    fit_failures: int
    seconds: float
    settled: list[Settledness | None] = Field(
        default_factory=list, description="the stopping signal (app.learning.settled) after each "
        "interaction that ends a batch, None after the others; empty unless asked for")
    gains: list[NextBatchGain | None] = Field(
        default_factory=list, description="what the next batch was expected to gain over θ* "
        "(app.learning.gain) after each interaction that ends a batch, None after the others; "
        "empty unless asked for")
    ties: int = Field(0, description="ties that entered the likelihood")
    hints: int = Field(0, description="coactive hints the participant gave")
    theta_star: list[float] = Field(
        default_factory=list, description="the final θ* of the condition's strategy, in the unit "
        "cube (empty in results stored before it was recorded)")

    @property
    def oracle_distances(self) -> list[float]:
        """The oracle curve: u of the best point shown so far."""
        return list(np.minimum.accumulate(self.shown_distances))


def participant_target(dim: int, seed: int, population: int, participant: int,
                       spread: float | PaperPopulation | None) -> np.ndarray:
    """The optimum θ_t of ``participant`` of ``population``: uniform, around the shared θ_0, or
    (``"paper"``) one of the θ* of Table II (even ``population``) or III (odd) with jitter."""
    rng = np.random.default_rng(derive_seed(seed, population, participant, 0))
    if spread is None:
        return rng.uniform(size=dim)
    if spread == PAPER_POPULATION:
        return paper_optimum(rng, population % 2, dim)
    shared = np.random.default_rng(derive_seed(seed, population, 0x5EED)).uniform(size=dim)
    return np.clip(shared + rng.normal(0.0, spread, size=dim), 0.0, 1.0)


def scale_position(y: float) -> float:
    """Where the simulated participant places an interaction observed as ``y`` (decreasing)."""
    return 0.5 - math.atan(y) / math.pi


def run_trial(condition: StudyCondition, seed: int, trial: int, settle: bool = False,
              spread: float | PaperPopulation | None = None) -> TrialResult:
    """Run trial ``trial`` of a study seeded with ``seed`` (``settle``: record the stopping
    signals; ``spread``: the participant of a population, :func:`trial_target`).

    Target and noise depend only on ``(seed, trial)``, so every condition sees the same targets and
    results do not depend on how trials are spread over processes.
    """
    return simulate_learner(condition, trial_target(condition.dim, seed, trial, spread),
                            derive_seed(seed, trial, 1), derive_seed(seed, trial, 2),
                            derive_seed(seed, trial, 3), trial=trial, settle=settle)[0]


def trial_target(dim: int, seed: int, trial: int,
                 spread: float | PaperPopulation | None = None) -> np.ndarray:
    """The optimum θ_t of trial ``trial`` of a study seeded with ``seed``: ~ U[0, 1]^dim, or with
    ``spread`` participant trial // 2 of scenario trial mod 2 (:func:`participant_target`; with
    ``"paper"`` the trials alternate between Tables II and III)."""
    if spread is not None:
        return participant_target(dim, seed, trial % 2, trial // 2, spread)
    return np.random.default_rng(derive_seed(seed, trial, 0)).uniform(size=dim)


def stop_point(result: TrialResult, schedule: BatchSchedule,
               rule: StoppingRule | GainRule) -> int:
    """The interactions a trial would have used had learning stopped by ``rule``: the end of the
    first learning batch at which the rule stops (on ``result.settled`` or, for a
    :class:`GainRule`, ``result.gains``), else the whole schedule. The stopped session is a
    prefix of the full one, so θ* when it stops is ``result.distances[stop − 1]``: the same
    participant, the same noise (paired by construction)."""
    for index in range(len(result.distances) - 1):
        slot = schedule.slot(index)
        if slot.kind is SlotKind.INITIAL:
            continue
        if isinstance(rule, GainRule):
            stops = index < len(result.gains) and rule.stops(slot.batch, result.gains[index])
        else:
            stops = index < len(result.settled) and rule.stops(slot.batch, result.settled[index])
        if stops:
            return index + 1
    return len(result.distances)


def stopped_theta_star(result: TrialResult, used: int) -> list[float]:
    """θ* (unit cube) when learning ended after ``used`` interactions (:func:`stop_point`): the
    θ* the stopping signals of that batch were about, or the final θ* after the whole schedule."""
    if used == len(result.distances):
        return result.theta_star
    signal = result.settled[used - 1] or result.gains[used - 1]
    assert signal is not None, "learning stops only where a stopping signal was recorded"
    return ParameterBox.unit_cube(len(signal.theta)).to_unit(signal.theta)


def participant_hint(condition: StudyCondition, box: ParameterBox, theta: dict[str, float],
                     utility: Callable[[dict[str, float]], float], rng: np.random.Generator,
                     mistakes: np.random.Generator | None = None) -> HintDirection | None:
    """The coactive hint of a simulated participant about the handover run with ``theta``: each
    way along :data:`HINTED_COORDINATES` that does not point past the box edge gains
    u(θ) − u(θ') (θ' the hinted θ, u the distance of eq. (15)), felt with noise σ; the best felt,
    if above ``condition.hint_threshold`` (:func:`~app.learning.coactive.felt_hint`). Wrong hints
    (``hint_flip``): the hint given points the other way. "Sooner" read as "faster"
    (``hint_faster``): the gain felt for "sooner" is that of moving the 1st coordinate up. Both
    mistakes are drawn from ``mistakes`` (default ``rng``), so that a generator of their own leaves
    the felt noise of the hints that of the same participant without mistakes."""
    mistakes = mistakes or rng
    faster = bool(condition.hint_faster) and mistakes.random() < condition.hint_faster
    gains: dict[HintDirection, float] = {}
    for i in (i for i in HINTED_COORDINATES if i < box.dim):
        for sign in (-1, 1):
            direction = HintDirection(parameter=box.names[i], sign=sign)
            # "sooner" (the δ analogue down) read as "faster": the 1st coordinate up
            meant = (HintDirection(parameter=box.names[0], sign=1)
                     if faster and i == HINTED_COORDINATES[0] and sign == -1 else direction)
            moved = hinted_theta(theta, box, meant, condition.hint_step)
            if moved is not None and hinted_theta(theta, box, direction,
                                                  condition.hint_step) is not None:
                gains[direction] = utility(theta) - utility(moved)
    hint = felt_hint(gains, condition.noise, condition.hint_threshold, rng)
    if hint is not None and condition.hint_flip and mistakes.random() < condition.hint_flip:
        return HintDirection(parameter=hint.parameter, sign=-hint.sign)
    return hint


def simulate_learner(condition: StudyCondition, target: np.ndarray, noise_seed: int,
                     learner_seed: int, hint_seed: int, *, trial: int = 0,
                     prior: PopulationPrior | None = None,
                     strategies: Sequence[RecommendationName] = (), settle: bool = False
                     ) -> tuple[TrialResult, PreferenceLearner]:
    """One simulated participant with optimum ``target`` through the schedule of ``condition``,
    with ``prior`` as the GP's prior mean; returns the trial and the final learner (whose
    snapshot feeds the priors of later participants). Hints (``condition.coactive``) draw their
    noise from ``hint_seed``'s generator alone, so the placements' noise is that of the same
    participant without hints (paired).

    The inference curve of the condition's strategy is recorded at every interaction, those of
    ``strategies`` too (each costs a recommendation per interaction, a box search for
    ``posterior_mean``); every other strategy only at the final interaction (NaN before). With
    ``settle`` the stopping signals (how settled θ*, what the next batch may gain) are recorded
    after every interaction that ends a batch."""
    start = time.monotonic()
    noise_rng = np.random.default_rng(noise_seed)
    hint_rng = np.random.default_rng(hint_seed)
    mistakes = np.random.default_rng([hint_seed, 0xE77])  # wrong hints, "sooner" read as "faster"
    box = ParameterBox.unit_cube(condition.dim)
    learner = PreferenceLearner(LearnerConfig(
        box=box, acquisition=condition.acquisition, schedule=condition.schedule,
        model=condition.model, optimizer=condition.optimizer,
        recommendation=condition.recommendation, prior=prior, seed=learner_seed))

    def distance(theta: dict[str, float]) -> float:
        return float(np.linalg.norm(target - np.array([theta[n] for n in box.names])))

    placements: list[Placement] = []
    felt: dict[str, float] = {}  # y of each interaction of the current batch
    shown: list[float] = []
    hints = 0
    settled: list[Settledness | None] = []
    gains: list[NextBatchGain | None] = []
    fits: list[FitReport] = []  # every fit the learner ran, once: in observe or before a query

    def count(report: FitReport) -> None:
        if not fits or report is not fits[-1]:
            fits.append(report)

    tracked = {s for s in strategies} | {condition.recommendation}
    curves: dict[RecommendationName, list[float]] = {s: [] for s in RecommendationName}
    while (suggestion := learner.suggest()).theta is not None:
        count(suggestion.fit)  # the study preset (lazy_fit) fits before a query
        slot = suggestion.slot
        if slot.position == 1:
            placements, felt = [], {}  # the scale is cleared after every batch
        u = distance(suggestion.theta)
        y = u + slot.position * noise_rng.normal(0.0, condition.noise)  # eq. (16)
        iid = str(slot.index + 1)
        placements.append(_placement(iid, y, felt, condition.tie))
        felt[iid] = y
        hinted: tuple[list[Interaction], list[Comparison]] = ([], [])
        if condition.coactive:
            hint = participant_hint(condition, box, suggestion.theta, distance, hint_rng,
                                    mistakes)
            if hint is not None:
                hinted = hint_observations(iid, hinted_theta(suggestion.theta, box, hint,
                                                             condition.hint_step))
                hints += 1
        count(learner.observe_many(
            [Interaction(interaction_id=iid, theta=suggestion.theta), *hinted[0]],
            [*comparisons_for_newest(placements, ties=True), *hinted[1]]))
        final = learner.next_slot().kind is SlotKind.DONE
        ends_batch = final or learner.next_slot().kind is SlotKind.BEST
        settled.append(learner.settledness() if settle and ends_batch else None)
        gains.append(learner.expected_gain() if settle and ends_batch else None)
        for strategy, curve in curves.items():
            curve.append(distance(best_theta(learner, strategy))
                         if final or strategy in tracked else math.nan)
        shown.append(u)
    result = TrialResult(trial=trial, distances=curves[condition.recommendation],
                         shown_distances=shown, strategy_distances=curves,
                         fit_failures=sum(f.fit_failed for f in fits),
                         seconds=time.monotonic() - start, settled=settled if settle else [],
                         gains=gains if settle else [],
                         ties=learner.data.n_ties, hints=hints,
                         theta_star=box.to_unit(best_theta(learner, condition.recommendation)))
    return result, learner


def best_theta(learner: PreferenceLearner, strategy: RecommendationName | None = None
               ) -> dict[str, float]:
    """θ* of a learner that has observed at least one interaction (by ``strategy``)."""
    best = learner.best(strategy)
    assert best is not None, "a learner that has observed an interaction has a θ*"
    return best.theta


def _placement(iid: str, y: float, felt: dict[str, float], tie: float) -> Placement:
    """The scale placement of an interaction felt as ``y``: "equal" to the earlier interaction of
    the batch felt closest, if closer than ``tie``; else at :func:`scale_position`."""
    closest = min(felt, key=lambda earlier: abs(felt[earlier] - y), default=None)
    if closest is not None and abs(felt[closest] - y) < tie:
        return Placement(interaction_id=iid, equal_to=closest)
    return Placement(interaction_id=iid, position=scale_position(y))
