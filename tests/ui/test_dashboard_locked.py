"""The locked dashboard, in Chromium against `handover serve`: only the token field — none of
viser's own chrome (the » arrow, the panel's drag bar, the settings gear with its editable server
address and Dev Settings) before the token; and STOP ARM's icon stands clear of its label (issue
45, item 17)."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.browser import button, chromium, open_page, serve, shot, unlock_dashboard, wait_text
from support.waiting import wait_for

pytestmark = [pytest.mark.browser]

SHOTS = Path("/tmp/dashboard-shots")
#: viser's chrome: the collapse arrows, the drag bars and resizers, the settings gear.
CHROME = ["[data-dock-region-handle]", "[data-dock-region-collapse]", "[data-dock-column-collapse]",
          "[data-dock-column-handle]", "[data-dock-griphandle]", "[data-dock-region-resize]",
          ".tabler-icon-adjustments", "text=Dev Settings"]
#: A ceiling for viser's fold of its server controls once the GUI has come (an animation of a few
#: hundred ms), not a measurement.
CHROME_SETTLES_S = 10.0
#: The left and right edges of a button's icon and of its label's text [px].
EDGES_JS = """e => { const icon = e.querySelector('svg').getBoundingClientRect();
  const text = document.createRange();
  text.selectNodeContents(e.querySelector('.mantine-Button-label'));
  const label = text.getBoundingClientRect();
  return [icon.left, icon.right, label.left, label.right]; }"""


def test_the_locked_dashboard_shows_no_chrome_and_stop_arms_icon_stands_clear(tmp_path: Path):
    """Slow: a `serve` and the dashboard's page in Chromium, locked until viser's chrome has folded
    away, then unlocked, with two screenshots."""
    with serve(tmp_path) as served, chromium() as browser:
        page = open_page(browser, served.dashboard_url, size=(1280, 720))
        wait_text(page, "Enter the dashboard token")

        def chrome() -> list[str]:
            return [selector for selector in CHROME
                    for element in page.locator(selector).all() if element.is_visible()]

        # viser shows its server controls (Dev Settings) until the first GUI arrives, then folds
        # them away with a short animation, which a loaded machine can catch half-way: the locked
        # page, once settled, shows none of its chrome (a chrome that stays fails here)
        wait_for(lambda: not chrome(), "the locked dashboard without viser's chrome",
                 timeout=CHROME_SETTLES_S, seen=chrome)
        shot(page, SHOTS, "dashboard-locked")
        unlock_dashboard(page)
        stop = button(page, "STOP ARM")
        icon_left, icon_right, label_left, label_right = stop.evaluate(EDGES_JS)
        stop.screenshot(path=str(SHOTS / "stop-arm.png"))
        assert icon_left < icon_right <= label_left < label_right, \
            f"the icon spans {icon_left:.0f}–{icon_right:.0f} px, the label {label_left:.0f}–" \
            f"{label_right:.0f} px"
        served.shutdown()
