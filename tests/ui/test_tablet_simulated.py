"""While the simulated participant rates (`serve --auto-participant`, a demo or a dry run), the
tablet that a person holds asks them nothing: it says "Please wait" where they would answer."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import (
    BRIEF_TOML,
    chromium,
    keep_starting,
    open_participant,
    open_screens,
    serve,
    shot,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Every title the tablet page shows from now on, in order (a MutationObserver on the page).
RECORD_TITLES = """() => {
  window.hlTitles = [];
  const note = () => document.querySelectorAll('.hl-title').forEach(t => {
    const text = t.innerText.trim();
    if (text && window.hlTitles[window.hlTitles.length - 1] !== text) window.hlTitles.push(text);
  });
  new MutationObserver(note).observe(document.body, {childList: true, subtree: true,
                                                     characterData: true});
  note();
}"""
#: What the tablet may show while the simulated participant answers for the session.
NOTHING_TO_ANSWER = {"Please wait", "Go!", "One moment", "Thank you!"}


def test_the_tablet_asks_nothing_while_the_simulated_participant_rates(tmp_path: Path) -> None:
    """Slow: a whole brief session on the wall clock, every handover of it, while the tablet page
    records every title it shows."""
    with serve(tmp_path, "--auto-participant", protocol_toml=BRIEF_TOML) as served, \
            chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        tablet.evaluate(RECORD_TITLES)
        open_participant(dashboard, "A01")
        keep_starting(dashboard, lambda: "Session complete" in dashboard.inner_text("body") or None)
        shot(tablet, tmp_path / "screens", "tablet-after-simulated-session")
        titles = tablet.evaluate("() => window.hlTitles")
        served.shutdown()
    assert "Go!" in titles and titles[-1] == "Thank you!", titles  # the session ran on this page
    assert set(titles) <= NOTHING_TO_ANSWER, f"the tablet showed {titles}"
