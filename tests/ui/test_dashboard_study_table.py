"""The Study table at 1280×720, and a session ended by the experimenter resumed by opening it again
(issue 37, item 9).

Each cell of the table stands on one line, apart from its neighbours (it read "perturbed34 of 34",
and statuses wrapped); a session the experimenter ended reads "ended early". Opening that
participant again resumes the session — the experimenter's resume, recorded as such (``resumed``,
"opened again by the experimenter") — so Start is not locked by a pause nobody asked for.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    chromium,
    click,
    open_page,
    open_participant,
    serve,
    shot,
    wait_text,
)

from app.session.runner import END_REASON, REOPEN_REASON
from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Per row of the first table: each cell's text as drawn — its lines (client rects of its text)
#: and its left and right edges.
CELLS_JS = """() => [...document.querySelector('table').rows].map(row => [...row.cells].map(cell => {
  const range = document.createRange(); range.selectNodeContents(cell);
  const lines = new Set([...range.getClientRects()].map(r => Math.round(r.top)));
  const box = range.getBoundingClientRect();
  return {text: cell.innerText.trim(), lines: lines.size, left: box.left, right: box.right};
}))"""
#: The least space between two cells' texts [px].
GAP_PX = 8


def cells_apart(dashboard: Page) -> list[list[dict]]:
    """The table's rows, having checked each cell is one line, at least GAP_PX from the next."""
    rows = dashboard.evaluate(CELLS_JS)
    for row in rows:
        for cell, after in pairwise(row):
            assert cell["lines"] == 1, f"{cell['text']!r} wraps: {row}"
            assert after["left"] - cell["right"] >= GAP_PX, \
                f"{cell['text']!r} runs into {after['text']!r}: {row}"
    return rows


def test_the_study_table_reads_apart_and_reopening_resumes(tmp_path: Path) -> None:
    """Slow: `handover serve` and Chromium; two participants created (each starting its learner)
    and one of them opened again."""
    screens = tmp_path / "screens"
    with serve(tmp_path) as served, chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=(1280, 720))
        open_participant(dashboard, "P01", "perturbed")  # the longer word: the cells stay apart
        click(dashboard, "End session")
        wait_text(dashboard, "No participant open")
        open_participant(dashboard, "P02", "perturbed")
        wait_text(dashboard, "ended early")
        rows = cells_apart(dashboard)
        assert [c["text"] for c in rows[1][:4]] == ["P01", "perturbed", "0 of 9", "ended early"]
        assert [c["text"] for c in rows[2][:4]] == ["P02", "perturbed", "0 of 9", "open now"]
        shot(dashboard, screens, "study-table-1280x720")
        click(dashboard, "End session")
        wait_text(dashboard, "No participant open")

        open_participant(dashboard, "P01")  # the experimenter opens it again: it resumes
        wait_text(dashboard, "Ready, but no tablet is connected")  # not "Paused"
        assert "session is paused" not in dashboard.inner_text("body")
        rows = cells_apart(dashboard)
        assert [c["text"] for c in rows[1][:4]] == ["P01", "perturbed", "0 of 9", "open now"]
        shot(dashboard, screens, "study-table-reopened")
        served.shutdown()
    store = ParticipantStore.open(served.study, "P01")
    try:
        events = [(e.kind, e.actor.value, e.payload.get("reason")) for e in store.events()
                  if e.kind in ("paused", "resumed", "session_resumed")]
    finally:
        store.close()
    assert events == [("paused", "experimenter", END_REASON), ("session_resumed", "system", None),
                      ("resumed", "experimenter", REOPEN_REASON)], events
