"""The refreshing relative scale → pairwise comparisons (Sect. III-C, Fig. 1).

After each interaction the participant places it on the scale among the earlier interactions of the
current batch. The newest interaction is compared with every earlier one of the batch: placed higher
means preferred, θ_new ≻ θ_earlier, lower means θ_earlier ≻ θ_new, and an "equal" placement (on an
earlier marker) makes no comparison. These comparisons extend the data set 𝒟 of eq. (11). The scale
is cleared after every batch, so the input is one batch's placements only.
"""

from __future__ import annotations

from collections.abc import Sequence

from app.learning.errors import ScaleError
from app.learning.models import Comparison, InteractionId, Placement


def _resolve(placements: Sequence[Placement]) -> tuple[dict[InteractionId, float],
                                                       dict[InteractionId, InteractionId]]:
    """Positions of all markers and the "equal" group (root marker) of each; validates the batch."""
    position: dict[InteractionId, float] = {}
    group: dict[InteractionId, InteractionId] = {}
    for index, placement in enumerate(placements):
        iid = placement.interaction_id
        if iid in position:
            raise ScaleError(
                f"placements[{index}].interaction_id = {iid!r} is already placed in this batch; "
                "each interaction is placed once")
        if placement.equal_to is None:
            assert placement.position is not None, "a Placement has a position or an equal_to"
            position[iid] = placement.position
            group[iid] = iid
        else:
            if placement.equal_to not in position:
                raise ScaleError(
                    f"placements[{index}].equal_to = {placement.equal_to!r} is not an earlier "
                    f"interaction of this batch (allowed: {sorted(position)})")
            position[iid] = position[placement.equal_to]
            group[iid] = group[placement.equal_to]
    return position, group


def comparisons_for_newest(placements: Sequence[Placement], *,
                           ties: bool = False) -> list[Comparison]:
    """Comparisons of the newest (last) placement against every earlier placement of the batch.

    Parameters
    ----------
    placements
        The batch's placements in the order the interactions happened; the last one is new.
    ties
        Also return a ``tie=True`` comparison (newest first) per earlier interaction tied with it.

    Returns
    -------
    list of Comparison
        One per earlier interaction that is not tied with the newest (with ``ties``: one per
        earlier interaction), in the order of the batch.
        Ties are placements on the same marker (``equal_to``, transitively); markers that happen to
        share a position without being placed on each other are also treated as ties, since the
        scale then carries no order between them.

    Raises
    ------
    ScaleError
        A second placement of the same interaction or ``equal_to`` naming no earlier interaction of
        the batch. Positions outside [0, 1] are rejected by :class:`Placement` itself.
    """
    if not placements:
        return []
    position, group = _resolve(placements)
    newest = placements[-1].interaction_id
    comparisons = []
    for earlier in placements[:-1]:
        eid = earlier.interaction_id
        if group[eid] == group[newest] or position[eid] == position[newest]:
            if ties:
                comparisons.append(Comparison(winner=newest, loser=eid, tie=True))
        elif position[newest] > position[eid]:
            comparisons.append(Comparison(winner=newest, loser=eid))
        else:
            comparisons.append(Comparison(winner=eid, loser=newest))
    return comparisons
