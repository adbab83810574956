"""The session's learner process as the engine uses it (:mod:`app.protocol.engine`): started when a θ
is needed — fresh, or restored from the store's last snapshot plus the placements (and hints) made
after it —, taught each placed interaction's observations while it runs, and its latest posterior
and stopping signals kept for the dashboard. It lives on the engine's thread.
"""

from __future__ import annotations

from collections.abc import Callable

from app.learning.coactive import hint_observations
from app.learning.config import LearnerConfig, LearnerSnapshot
from app.learning.models import Comparison as LearnedComparison
from app.learning.models import (
    Interaction,
    NextBatchGain,
    PosteriorSlice,
    Settledness,
    Suggestion,
)
from app.learning.models import Placement as ScalePlacement
from app.learning.prior import PopulationPrior
from app.learning.scale import comparisons_for_newest
from app.learning.worker import LearnerClient
from app.protocol.plan import Slot
from app.protocol.session_inputs import learner_config
from app.protocol.state import SessionState
from app.protocol.study_config import StudyConfig
from session_store.models import HintRow, LearnerSnapshotRow
from session_store.store import ParticipantStore

LearnerFactory = Callable[[LearnerConfig, LearnerSnapshot | None], LearnerClient]


def scale_placement(interaction: int, position: float, equal_to: int | None) -> ScalePlacement:
    """A marker of the scale as the learner's scale rule takes it (on an earlier one, or placed)."""
    return ScalePlacement(interaction_id=str(interaction),
                          position=None if equal_to is not None else position,
                          equal_to=None if equal_to is None else str(equal_to))


class SessionLearner:
    """One session's learner: :meth:`running` starts it when a θ is needed."""

    def __init__(self, store: ParticipantStore, config: StudyConfig, slots: list[Slot],
                 factory: LearnerFactory) -> None:
        self.store, self.config, self.slots, self._factory = store, config, slots, factory
        self._learner: LearnerClient | None = None
        #: the posterior utility through θ* after the latest learner reply (for the dashboard)
        self.posterior_slices: list[PosteriorSlice] = []
        #: the stopping signal after the latest learning batch (for the dashboard), None before one
        self.settledness: Settledness | None = None
        #: what the next batch may gain over θ* after the latest batch (stop_when_no_gain), ditto
        self.gain: NextBatchGain | None = None

    @property
    def pid(self) -> int | None:
        """The learner process's id (None: none runs)."""
        return None if self._learner is None else self._learner.pid

    def close(self) -> None:
        """End the learner process (a later :meth:`running` starts a new one, restored)."""
        if self._learner is not None:
            self._learner.close()
            self._learner = None

    @staticmethod
    def observations(state: SessionState, interaction: int, learned: list[LearnedComparison],
                     hint: HintRow | None) -> tuple[list[Interaction], list[LearnedComparison]]:
        """What the learner gets for a placed interaction: its θ with the placement's comparisons
        (``learned``, ties included), and the hint's stored θ' ≻ θ if one was given."""
        theta = state.planned[interaction].theta.model_dump()
        more, hinted = hint_observations(str(interaction), None if hint is None else hint.hinted)
        return [Interaction(interaction_id=str(interaction), theta=theta), *more], [*learned, *hinted]

    def teach(self, state: SessionState, slot: Slot, learned: list[LearnedComparison],
              hint: HintRow | None) -> None:
        """Send an interaction's observations to the running learner. A session resumed in a fresh
        process has no learner yet: the next plan_next starts it, restored from the store (which
        holds them). Starting it here held the participant's Confirm for as long as a first
        learner process takes to import (13–18 s)."""
        if slot.learner_index is not None and self._learner is not None:
            self._learner.submit(*self.observations(state, slot.interaction, learned, hint))

    def running(self, state: SessionState, prior: PopulationPrior | None) -> LearnerClient:
        """The learner process: fresh, or restored from the last stored snapshot plus the
        placements made after it."""
        if self._learner is not None:
            return self._learner
        config = learner_config(self.config, prior)
        snapshots = self.store.rows("learner_snapshots")
        snapshot = LearnerSnapshot.model_validate_json(snapshots[-1].state) if snapshots else None
        self._learner = self._factory(config, snapshot)
        known = {i.interaction_id for i in snapshot.interactions} if snapshot else set()
        placements = self.store.rows("placements", order_by="interaction")
        hints = {h.interaction: h for h in self.store.rows("hints")}
        # with coactive hints, the learner hears of a placement with its hint (HINT: not yet)
        later = [p for p in placements if str(p.interaction) not in known
                 and self.slots[p.interaction - 1].learner_index is not None
                 and (not state.coactive or p.interaction in hints)]
        for placement in later:
            # The scale as it stood when it was made, so the comparisons (and ties) come in the
            # order the live learner received them: another order feeds PairwiseGP other θ.
            scale = [scale_placement(p.interaction, p.position, p.equal_to) for p in placements
                     if p.batch == placement.batch and p.interaction <= placement.interaction]
            self._learner.submit(*self.observations(
                state,                 placement.interaction, comparisons_for_newest(scale, ties=True),
                hints.get(placement.interaction)))
        if not later:
            self._learner.submit()
        return self._learner

    def suggestion(self, state: SessionState, prior: PopulationPrior | None, timeout: float
                   ) -> tuple[Suggestion, LearnerClient]:
        """The learner's next suggestion, and the learner (started if need be)."""
        learner = self.running(state, prior)
        suggestion = learner.get(timeout)
        self.posterior_slices = learner.slices or self.posterior_slices
        self.settledness = learner.settledness or self.settledness
        self.gain = learner.gain or self.gain
        return suggestion, learner

    @staticmethod
    def snapshot_row(learner: LearnerClient, after: int, suggestion: Suggestion
                      ) -> LearnerSnapshotRow | None:
        """The learner's snapshot to store with a planned θ; None while the learner has never
        replied (a fresh learner late with its first reply, e.g. still importing under load, gave a
        fallback θ): there is no state to store, and a resume without a snapshot is exactly that
        learner — fresh, given the placements made since (:meth:`running`)."""
        if learner.state is None:
            return None
        best = learner.best
        return LearnerSnapshotRow(
            after_interaction=after, theta_star_a=best.theta["a"] if best else None,
            theta_star_delta=best.theta["delta"] if best else None,
            theta_star_k=best.theta["k"] if best else None,
            utility_mean=best.utility_mean if best else None,
            fit_failed=suggestion.fit.fit_failed, message=suggestion.fit.message,
            n_points=suggestion.fit.n_points, n_comparisons=suggestion.fit.n_comparisons,
            state=learner.state.model_dump_json())
