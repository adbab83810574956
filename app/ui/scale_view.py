"""The refreshing relative scale as the tablet draws it (Sect. III-C, Fig. 1).

One horizontal arrow from "Strongly Worse" (0) to "Strongly Better" (1). The batch's earlier
interactions stand on it as numbered markers where they were placed; markers placed "equal" stand
stacked in one column; markers placed close together (closer than :data:`APART`, not "equal") stand
at different heights, so that none hides another's number. The newest marker (orange) follows the
participant's finger: it is dragged with a full-width slider right under the arrow (viser's slider
works with touch and mouse; its multi-slider does not), and dropping it within :data:`SNAP` of an
earlier marker means "equal" and is drawn stacked on that marker. The handle starts at
:func:`start_position`, never on an earlier marker, so an untouched handle can never mean "equal".
The lane has a fixed height (CSS): a taller stack closes up instead of pushing the rest of the
screen down. This module is pure: markers in, HTML out.
"""

from __future__ import annotations

from collections.abc import Sequence
from html import escape
from itertools import pairwise

from app.protocol.state import Marker

#: A drop closer than this (in scale units, 0…1) to an earlier marker counts as "equal" to it.
SNAP = 0.025
#: The handle starts this far (scale units) from every earlier marker.
CLEARANCE = 3 * SNAP
#: Columns of markers closer than this (scale units) stand at different heights: a marker is at
#: most ~0.09 of the scale wide (64 px of the ~720 px scale of a tablet held upright, 820 px).
APART = 0.1


def snap(position: float, markers: Sequence[Marker]) -> Marker | None:
    """The earlier marker a drop at ``position`` lands on ("equal"), if any: the nearest within
    :data:`SNAP`."""
    near = [(abs(m.position - position), i, m) for i, m in enumerate(markers)
            if abs(m.position - position) <= SNAP]
    return min(near)[2] if near else None


def start_position(markers: Sequence[Marker]) -> float:
    """Where the handle starts: the centre if no earlier marker is within :data:`CLEARANCE` of it,
    else the middle of the widest gap between the ends and the markers (never on a marker)."""
    positions = sorted({m.position for m in markers})
    if all(abs(p - 0.5) > CLEARANCE for p in positions):
        return 0.5
    edges = [0.0, *positions, 1.0]
    low, high = max(pairwise(edges), key=lambda gap: gap[1] - gap[0])
    return round((low + high) / 2, 3)


def _columns(markers: Sequence[Marker]) -> dict[float, list[int]]:
    """Marker labels by their position on the scale (equal ones share a position)."""
    columns: dict[float, list[int]] = {}
    for marker in markers:
        columns.setdefault(marker.position, []).append(marker.label)
    return columns


def _free_level(position: float, size: int, base: dict[float, int],
                columns: dict[float, list[int]], lowest: int = 0) -> int:
    """The lowest level (≥ ``lowest``) where ``size`` markers at ``position`` overlap no column
    already placed (``base``: each column's lowest level) closer than :data:`APART`."""
    taken = [(base[p], base[p] + len(columns[p])) for p in base if abs(p - position) < APART]
    level = lowest
    while any(level < top and bottom < level + size for bottom, top in taken):
        level += 1
    return level


def _levels(columns: dict[float, list[int]]) -> dict[float, int]:
    """Each column's lowest level, placed left to right: a column stands clear of every close one
    already placed."""
    base: dict[float, int] = {}
    for position in sorted(columns):
        base[position] = _free_level(position, len(columns[position]), base, columns)
    return base


def _marker(label: int, left: float, level: int, newest: bool) -> str:
    kind = "hl-marker hl-new" if newest else "hl-marker"
    return (f'<div class="{kind}" style="left:{100 * left:.2f}%;--hl-level:{level}">'
            f"{label}</div>")


def render_scale(markers: Sequence[Marker], newest_label: int, position: float,
                 hint: str = "") -> str:
    """The scale with the earlier ``markers`` and the newest one at ``position`` (stacked on an
    earlier marker when it snaps to it, else at the lowest level clear of close markers); ``hint``
    in the caption's place until the handle lands on a marker (the caption's height is kept, so
    nothing below it moves when the hint goes)."""
    columns = _columns(markers)
    base = _levels(columns)
    landed = snap(position, markers)
    parts = []
    for left, labels in columns.items():
        parts += [_marker(label, left, base[left] + level, False)
                  for level, label in enumerate(labels)]
    if landed is None:
        level = _free_level(position, 1, base, columns)
    else:
        level = _free_level(landed.position, 1, base, columns,
                            lowest=base[landed.position] + len(columns[landed.position]))
    parts.append(_marker(newest_label, position if landed is None else landed.position, level, True))
    # The stack step depends only on the earlier markers, so nothing moves when the newest snaps.
    gaps = max([base[left] + len(labels) for left, labels in columns.items()] + [1])
    caption = (f"Same as {landed.label}" if landed is not None
               else f'<span class="hl-hint">{escape(hint)}</span>' if hint else "&nbsp;")
    return (f'<div class="hl-scale"><div class="hl-caption">{caption}</div>'
            f'<div class="hl-lane" style="--hl-gaps:{gaps}">{"".join(parts)}</div>'
            f'<div class="hl-arrow"></div>'
            f'<div class="hl-ends"><span>Strongly Worse</span><span>Strongly Better</span></div>'
            f'</div>')


def screen_text(title: str, detail: str = "", kind: str = "") -> str:
    """A large centred message ("Please wait", "Go!", a question)."""
    detail_html = f'<div class="hl-detail">{escape(detail)}</div>' if detail else ""
    return f'<div class="hl-title {kind}">{escape(title)}</div>{detail_html}'
