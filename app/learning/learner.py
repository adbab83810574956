"""The session-level preference learner: data + model + acquisition + schedule, composed.

Typical use by a session engine (or through :mod:`app.learning.worker` in its own process)::

    learner = PreferenceLearner(LearnerConfig(box=ParameterBox.from_bounds(THETA_BOUNDS), seed=7))
    suggestion = learner.suggest()                  # θ for interaction 0 (a Sobol point)
    ...run the handover with suggestion.theta, collect the participant's placement...
    comparisons = comparisons_for_newest(batch_placements)   # app.learning.scale
    learner.observe(Interaction(interaction_id="1", theta=suggestion.theta), comparisons)
    learner.best()                                  # θ*, by LearnerConfig.recommendation
    learner.snapshot()                              # everything needed to rebuild it

Every step is deterministic given ``LearnerConfig.seed`` and the observations.
"""

from __future__ import annotations

import bisect
import logging
from collections.abc import Sequence

import torch

from app.learning.acquisition import propose, sobol_points
from app.learning.config import AcquisitionName, Hyperparameters, LearnerConfig, LearnerSnapshot
from app.learning.data import PreferenceData
from app.learning.errors import UnknownInteractionError
from app.learning.gain import best_gain
from app.learning.models import (
    BestPoint,
    Comparison,
    FitReport,
    Interaction,
    NextBatchGain,
    PosteriorSlice,
    RecommendationName,
    Settledness,
    Slot,
    SlotKind,
    Suggestion,
)
from app.learning.population import PopulationMean
from app.learning.preference_model import PreferenceModel, kernel_evaluation, posterior_at
from app.learning.recommendation import Recommendation, recommend
from app.learning.rng import derive_seed, seeded
from app.learning.settled import regrets

logger = logging.getLogger(__name__)


class PreferenceLearner:
    """Turns interactions and their comparisons into the next θ and the best θ*."""

    def __init__(self, config: LearnerConfig,
                 hyperparameters: Hyperparameters | None = None) -> None:
        self.config = config
        self.data = PreferenceData(config.box.dim, ties=config.model.ties)
        prior_mean = PopulationMean(config.prior) if config.prior is not None else None
        self.model = PreferenceModel(config.model, hyperparameters, prior_mean)
        self.last_fit = FitReport()
        self._interactions: list[Interaction] = []
        self._comparisons: list[Comparison] = []
        self._recommended: tuple[object, int, dict[RecommendationName, Recommendation]] = (
            None, 0, {})

    @property
    def n_interactions(self) -> int:
        """Handovers run (the points coactive hints named are not counted)."""
        return sum(i.shown for i in self._interactions)

    def next_slot(self) -> Slot:
        """Where the next interaction sits in the schedule."""
        return self.config.schedule.slot(self.n_interactions)

    def observe(self, interaction: Interaction,
                comparisons: Sequence[Comparison] = ()) -> FitReport:
        """Record one interaction and the comparisons its placement produced, then refit.

        Returns the report of this update (``refitted=False`` when nothing new was learned, e.g. a
        tie or the first interaction of a batch); :attr:`last_fit` is the last fit attempted.
        """
        return self.observe_many([interaction], comparisons)

    def observe_many(self, interactions: Sequence[Interaction],
                     comparisons: Sequence[Comparison]) -> FitReport:
        """Record several interactions and comparisons (e.g. a replay) with a single update.

        Comparisons may name any interaction known after ``interactions`` are added. The θ of an
        interaction is what was actually run, which need not be the learner's suggestion. Input is
        validated before anything is recorded, so a rejected call leaves the learner unchanged.
        """
        if not self._record(interactions, comparisons):
            return FitReport(n_points=len(self.data.points),
                             n_comparisons=len(self.data.comparisons))
        fit = not self.config.model.lazy_fit and self.model.needs_fit(self.data)
        return self._update(fit_hyperparameters=fit)

    def _record(self, interactions: Sequence[Interaction],
                comparisons: Sequence[Comparison]) -> bool:
        """Validate, then add the observations; True if any comparison carries information."""
        units = [self.config.box.to_unit(i.theta) for i in interactions]
        new_ids = [i.interaction_id for i in interactions]
        self.data.check_new_ids(new_ids)
        known = self.data.known_ids | set(new_ids)
        for comparison in comparisons:
            for iid in (comparison.winner, comparison.loser):
                if iid not in known:
                    raise UnknownInteractionError(
                        f"comparison names interaction_id = {iid!r}, which is not known")
        for interaction, unit in zip(interactions, units, strict=True):
            # j of eq. (16); a hinted point is judged at once, against the handover just felt
            position = (self.config.schedule.slot(self.n_interactions).position
                        if interaction.shown else 1)
            self.data.add_interaction(interaction.interaction_id, unit, position,
                                      shown=interaction.shown)
            self._interactions.append(interaction)
        added = [self.data.add_comparison(c) for c in comparisons]
        self._comparisons.extend(comparisons)
        return any(added)

    def _update(self, *, fit_hyperparameters: bool) -> FitReport:
        with seeded(derive_seed(self.config.seed, self.n_interactions, 1)):
            self.last_fit = self.model.update(self.data, fit_hyperparameters=fit_hyperparameters)
        return self.last_fit

    def best(self, strategy: RecommendationName | None = None) -> BestPoint | None:
        """θ*, recommended by ``strategy`` (default: ``LearnerConfig.recommendation``).

        Before any model exists (no comparisons yet, e.g. only ties) it is the first point shown;
        ``None`` before any interaction.
        """
        if not self.data.points:
            return None
        strategy = strategy or self.config.recommendation
        found = self._recommendation(strategy)
        if found is None:
            return BestPoint(theta=self.config.box.from_unit(self.data.points[0]),
                             interaction_ids=self.data.interactions_at(0), utility_mean=None)
        ids = () if found.observed_index is None else self.data.interactions_at(found.observed_index)
        return BestPoint(theta=self.config.box.from_unit(found.unit), interaction_ids=ids,
                         utility_mean=found.mean, strategy=strategy)

    def _recommendation(self, strategy: RecommendationName) -> Recommendation | None:
        model = self.model.model
        if model is None:
            return None
        cached_model, size, found = self._recommended
        if cached_model is not model or size != len(self.data.points):
            found = {}  # the box search costs an optimisation: once per model and strategy
            self._recommended = (model, len(self.data.points), found)
        if strategy not in found:
            seed = derive_seed(self.config.seed, len(self.data.points), len(self.data.comparisons), 3)
            with kernel_evaluation(self.config.model):
                found[strategy] = recommend(strategy, model, self.data, self.config.optimizer,
                                            seed, self.config.lcb_beta)
        return found[strategy]

    def settledness(self) -> Settledness | None:
        """The stopping signal (:mod:`app.learning.settled`): how sure the posterior is that θ*'s
        regret is at most ``LearnerConfig.settled_epsilon``; None before a model exists."""
        best = self.best()
        if best is None or best.strategy is None or self.model.model is None:
            return None
        seed = derive_seed(self.config.seed, len(self.data.points), len(self.data.comparisons), 4)
        with kernel_evaluation(self.config.model):
            drawn = regrets(self.model.model, self.data, self.config.box.to_unit(best.theta),
                            seed)
        epsilon = self.config.settled_epsilon
        share = bisect.bisect_right(drawn, epsilon) / len(drawn)
        return Settledness(probability=share, epsilon=epsilon, regrets=tuple(drawn),
                           theta=best.theta)

    def expected_gain(self) -> NextBatchGain | None:
        """What the next batch is expected to gain over θ* (:mod:`app.learning.gain`): the largest
        E[(u(θ) − u(θ*))⁺] over the box, for the q − 1 new handovers of a batch; None before a
        model exists."""
        best = self.best()
        if best is None or best.strategy is None or self.model.model is None:
            return None
        seed = derive_seed(self.config.seed, len(self.data.points), len(self.data.comparisons), 5)
        with kernel_evaluation(self.config.model):
            gain, unit = best_gain(self.model.model, self.config.box.to_unit(best.theta),
                                   self.config.optimizer, seed)
        return NextBatchGain(gain=gain, queries=self.config.schedule.q - 1, theta=best.theta,
                             candidate=self.config.box.from_unit(unit))

    def incumbent(self) -> dict[str, float] | None:
        """The batch-opening θ*: the observed point with the largest posterior mean, a handover
        the participant has felt (the reference of the refreshing scale); the first point shown
        before a model exists, ``None`` before any interaction."""
        if not self.data.points:
            return None
        best = self.model.best(self.data)
        index = best[0] if best is not None else 0
        return self.config.box.from_unit(self.data.points[index])

    def suggest(self) -> Suggestion:
        """The θ for the next interaction of the schedule (``theta=None`` once it is done)."""
        slot = self.next_slot()
        if slot.kind is SlotKind.DONE:
            return Suggestion(theta=None, slot=slot, fit=self.last_fit)
        if slot.kind is SlotKind.BEST:
            theta = self.incumbent()  # the initial batch precedes: points exist
            return Suggestion(theta=theta, slot=slot, fit=self.last_fit)
        unit = self._query(slot) if slot.kind is SlotKind.QUERY else self._initial(slot)
        return Suggestion(theta=self.config.box.from_unit(unit.tolist()), slot=slot,
                          fit=self.last_fit)  # after _query, which may have refitted

    def posterior_slices(self, points: int = 41) -> list[PosteriorSlice]:
        """The posterior utility along each parameter through θ* (the others held at θ*), for the
        experimenter's learner panel; empty before a model exists."""
        best = self.model.best(self.data)
        model = self.model.model
        if best is None or model is None:
            return []
        center = torch.tensor(self.data.points[best[0]], dtype=torch.float64)
        grid = torch.linspace(0.0, 1.0, points, dtype=torch.float64)
        box = self.config.box
        slices = []
        for i, name in enumerate(box.names):
            X = center.repeat(points, 1)
            X[:, i] = grid
            with kernel_evaluation(self.config.model):
                mean, std = posterior_at(model, X)
            values = box.lower[i] + grid * (box.upper[i] - box.lower[i])
            slices.append(PosteriorSlice(parameter=name, values=tuple(values.tolist()),
                                         mean=tuple(mean.tolist()), std=tuple(std.tolist())))
        return slices

    def snapshot(self) -> LearnerSnapshot:
        """Plain-data state for storage; :meth:`restore` rebuilds an equivalent learner."""
        return LearnerSnapshot(config=self.config, interactions=list(self._interactions),
                               comparisons=list(self._comparisons),
                               hyperparameters=self.model.hyperparameters,
                               fitted_comparisons=self.model.fitted_comparisons,
                               last_fit=self.last_fit)

    @classmethod
    def restore(cls, snapshot: LearnerSnapshot) -> PreferenceLearner:
        """The learner that was stored: its observations, and its hyperparameters adopted without a
        fit, so its next suggestions are exactly those the stored learner would have made, with the
        same fit report (an older snapshot without one: the counts of the restored data)."""
        learner = cls(snapshot.config, snapshot.hyperparameters)
        learner._record(snapshot.interactions, snapshot.comparisons)
        learner.model.restore(learner.data, snapshot.fitted_comparisons)
        learner.last_fit = snapshot.last_fit or FitReport(
            n_points=len(learner.data.points), n_comparisons=len(learner.data.comparisons))
        return learner

    def _initial(self, slot: Slot) -> torch.Tensor:
        """A point of the initial batch: with a prior from earlier participants, the handovers
        they liked best (:meth:`PopulationMean.initial_design`: the pooled best, then their own
        bests spread out), so θ* can be good from the first batch on and the first comparisons
        tell where this participant differs from them; otherwise, and for slots the earlier
        participants cannot fill, the Sobol sequence."""
        prior_mean = self.model.prior_mean
        if prior_mean is not None:
            design = prior_mean.initial_design(self.config.schedule.n_initial)
            if slot.index < len(design):
                return design[slot.index].clone()
        return self._sobol(slot)

    def _sobol(self, slot: Slot) -> torch.Tensor:
        """Point ``slot.index`` of the learner's Sobol sequence (initial batch, baseline)."""
        return sobol_points(self.config.box.dim, self.config.seed, slot.index, 1)[0]

    def _query(self, slot: Slot) -> torch.Tensor:
        # A due hyperparameter fit happens here for every acquisition, Sobol included: θ* of the
        # baseline must come from a model fitted as often as the learning conditions' models.
        if self.model.needs_fit(self.data):
            self._update(fit_hyperparameters=True)
        model = self.model.model  # after the fit above, if one was due
        acquisition = self.config.acquisition
        if acquisition is AcquisitionName.SOBOL or model is None:
            if model is None:
                logger.info("no preference model yet (no comparisons): Sobol point for slot %d",
                            slot.index)
            return self._sobol(slot)
        found = self.model.best(self.data)
        assert found is not None, "a model exists here"
        index, _ = found
        best_x = torch.tensor(self.data.points[index], dtype=torch.float64)
        with kernel_evaluation(self.config.model):
            return propose(acquisition, model, best_x, self.config.optimizer,
                           derive_seed(self.config.seed, slot.index, 2))
