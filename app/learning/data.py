"""The data set 𝒟 of eq. (11) in the form BoTorch's ``PairwiseGP`` takes it.

Unique points (unit-cube coordinates) and comparisons as ``[winner, loser]`` row indices into them.
Interactions map to point indices: an interaction that shows a θ already seen (θ* opening a batch)
reuses that point's index. ``PairwiseGP`` would silently merge points closer than 1e-4 and turn a
comparison with such a near-twin into an uninformative self-pair, so points are merged here first,
with a larger tolerance, and comparisons that end up between one point and itself are dropped.

Ties ("equal" placements, ``Comparison.tie``) are dropped (the paper's rule) or, with
``TieHandling.MODEL``, enter as two weighted rows (:mod:`app.learning.ties`).
"""

from __future__ import annotations

import logging
import math

import torch

from app.learning.comparison_noise import relative_noise
from app.learning.errors import UnknownInteractionError
from app.learning.models import Comparison, InteractionId, TieHandling
from app.learning.ties import tie_rows

logger = logging.getLogger(__name__)

#: Points closer than this in every unit-cube coordinate are one point (PairwiseGP merges at 1e-4).
MERGE_TOLERANCE = 1e-3


class PreferenceData:
    """Unique points, the interactions that showed them, and index comparisons."""

    def __init__(self, dim: int, merge_tolerance: float = MERGE_TOLERANCE,
                 ties: TieHandling = TieHandling.DROP) -> None:
        self.dim = dim
        self.merge_tolerance = merge_tolerance
        self.ties = ties
        self.points: list[list[float]] = []
        #: per point: some interaction showed it (False: only coactive hints named it)
        self.shown: list[bool] = []
        self.comparisons: list[tuple[int, int]] = []
        #: each comparison's relative noise √((i² + j²)/2) from its batch positions (eq. (16))
        self.comparison_noise: list[float] = []
        #: each comparison's weight in the likelihood: 1, or ½ for each half of a tie
        self.comparison_weight: list[float] = []
        #: ties that entered the likelihood (two rows each)
        self.n_ties = 0
        self._index: dict[InteractionId, int] = {}
        self._position: dict[InteractionId, int] = {}

    @property
    def n_interactions(self) -> int:
        return len(self._index)

    @property
    def known_ids(self) -> set[InteractionId]:
        return set(self._index)

    def check_new_ids(self, interaction_ids: list[InteractionId]) -> None:
        """Raise if any id is already known or repeated: each interaction is added once."""
        seen = set(self._index)
        for iid in interaction_ids:
            if iid in seen:
                raise UnknownInteractionError(
                    f"interaction_id = {iid!r} was already added; ids must be unique")
            seen.add(iid)

    def index_of(self, interaction_id: InteractionId) -> int:
        try:
            return self._index[interaction_id]
        except KeyError:
            raise UnknownInteractionError(
                f"interaction_id = {interaction_id!r} is unknown; known: {sorted(self._index)}"
            ) from None

    def interactions_at(self, index: int) -> tuple[InteractionId, ...]:
        """The interactions that showed point ``index``, in the order they were added."""
        return tuple(iid for iid, i in self._index.items() if i == index)

    def add_interaction(self, interaction_id: InteractionId, unit_point: list[float],
                        position: int = 1, shown: bool = True) -> int:
        """Register an interaction at a unit-cube point and its ``position`` j within its batch
        (eq. (16)); ``shown=False``: a point a coactive hint named. Returns its (possibly reused)
        point index."""
        self.check_new_ids([interaction_id])
        index = self._find(unit_point)
        if index is None:
            index = len(self.points)
            self.points.append(list(unit_point))
            self.shown.append(shown)
        else:
            logger.debug("interaction %s reuses point %d", interaction_id, index)
            self.shown[index] = self.shown[index] or shown
        self._index[interaction_id] = index
        self._position[interaction_id] = position
        return index

    def add_comparison(self, comparison: Comparison) -> bool:
        """Add θ_winner ≻ θ_loser (a tie: both orders, half weight each, or nothing when ties
        are dropped); returns False (and adds nothing) when both are the same point."""
        pair = (self.index_of(comparison.winner), self.index_of(comparison.loser))
        if pair[0] == pair[1] or (comparison.tie and self.ties is TieHandling.DROP):
            logger.debug("dropped %s %s ~ %s (points %d, %d)",
                         "tie" if comparison.tie else "self-comparison", comparison.winner,
                         comparison.loser, *pair)
            return False
        rows = tie_rows(*pair) if comparison.tie else [(pair, 1.0)]
        noise = relative_noise(self._position[comparison.winner], self._position[comparison.loser])
        for row, weight in rows:
            self.comparisons.append(row)
            self.comparison_noise.append(noise)
            self.comparison_weight.append(weight)
        self.n_ties += comparison.tie
        return True

    def tensors(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``(n × d float64 points, m × 2 long comparisons)`` for ``PairwiseGP``."""
        X = torch.tensor(self.points, dtype=torch.float64).reshape(-1, self.dim)
        C = torch.tensor(self.comparisons, dtype=torch.long).reshape(-1, 2)
        return X, C

    def unshown_penalty(self) -> torch.Tensor:
        """0 at the points a handover showed, −inf at those only hints named: added to a score over
        :meth:`tensors`' points, its argmax is a shown point (θ* in the sample is one felt)."""
        return torch.tensor([0.0 if s else -math.inf for s in self.shown], dtype=torch.float64)

    def _find(self, unit_point: list[float]) -> int | None:
        for index, point in enumerate(self.points):
            gap = max(abs(a - b) for a, b in zip(point, unit_point, strict=True))
            if gap <= self.merge_tolerance:
                return index
        return None
