"""STOP ARM stays on screen whatever the experimenter clicks or drags (issue 37, item 2).

At 1280×720 and 1440×900, every control viser's page offers besides the dashboard's own buttons and
fields — collapse arrows, panel headers and tabs, grab handles, resizers and dividers, folder
titles, header icons — is found in the DOM (not from a fixed list), clicked, and dragged if it
looks draggable; controls that appear meanwhile (a palette, a modal) are tried as well. After each,
STOP ARM must lie wholly in the window with nothing over its centre. At the end it still stops the
arm.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    chromium,
    click,
    in_viewport,
    open_page,
    open_participant,
    serve,
    shot,
    wait_still,
    wait_text,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: The page's own controls, besides the dashboard's buttons, fields and boxes: what is clickable
#: (a button, a role, a tab stop) or looks draggable (its cursor), visible, and the element hit at
#: its centre. ``drag``: whether a drag is tried on it too.
CONTROLS_JS = """() => {
  const ours = e => e.closest('.mantine-Button-root, input, textarea, select, .mantine-Slider-root');
  const dragging = ['grab', 'grabbing', 'move', 'col-resize', 'row-resize', 'ew-resize',
                    'ns-resize', 'ew-resize', 'nwse-resize', 'nesw-resize'];
  const out = [];
  for (const e of document.querySelectorAll('body *')) {
    const cursor = getComputedStyle(e).cursor;
    const clickable = e.matches('button, [role=button], [role=tab], [tabindex], a[href], summary')
      || cursor === 'pointer' || dragging.includes(cursor);
    if (!clickable || ours(e)) continue;
    const r = e.getBoundingClientRect();
    if (r.width < 1 || r.height < 1 || r.right < 0 || r.bottom < 0 || r.left > innerWidth
        || r.top > innerHeight) continue;
    const x = Math.min(Math.max(r.left + r.width / 2, 1), innerWidth - 1);
    const y = Math.min(Math.max(r.top + r.height / 2, 1), innerHeight - 1);
    const hit = document.elementFromPoint(x, y);
    if (!hit || !(e === hit || e.contains(hit))) continue;
    const attrs = [...e.attributes].filter(a => a.name !== 'style'
      && !a.name.startsWith('aria-expanded')).map(a => a.name + '=' + a.value).join(' ');
    out.push({key: e.tagName + ' ' + attrs + ' ' + (e.textContent || '').slice(0, 40),
              x, y, drag: dragging.includes(cursor)});
  }
  return out;
}"""
#: A page has a few dozen such controls; more means the loop found a control that makes new ones.
MOST_CONTROLS = 80


def stop_stays_on_screen(dashboard: Page) -> list[str]:
    """Try every control of the page once (those it shows after each try included), checking
    STOP ARM after each; return the controls tried."""
    tried: list[str] = []
    while len(tried) < MOST_CONTROLS:
        fresh = [c for c in dashboard.evaluate(CONTROLS_JS) if c["key"] not in tried]
        if not fresh:
            return tried
        control = fresh[0]
        tried.append(control["key"])
        dashboard.mouse.click(control["x"], control["y"])
        if control["drag"]:
            dashboard.mouse.move(control["x"], control["y"])
            dashboard.mouse.down()
            dashboard.mouse.move(control["x"] - 400, control["y"] + 300, steps=8)
            dashboard.mouse.up()
        wait_still(dashboard)
        assert in_viewport(dashboard, "STOP ARM"), \
            f"STOP ARM is off screen or covered after trying {control}"
    raise AssertionError(f"more than {MOST_CONTROLS} controls: {tried[-5:]}")


@pytest.mark.parametrize("size", [(1280, 720), (1440, 900)], ids=["1280x720", "1440x900"])
def test_no_control_of_the_page_hides_stop_arm(tmp_path: Path, size: tuple[int, int]) -> None:
    """Slow (~20 s in a loaded full run): every control of the dashboard is tried once in Chromium,
    STOP ARM's place checked after each."""
    with serve(tmp_path) as served, chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=size)
        open_participant(dashboard, "P01")
        assert in_viewport(dashboard, "STOP ARM")
        tried = stop_stays_on_screen(dashboard)
        shot(dashboard, tmp_path / "screens", f"after-every-control-{size[0]}x{size[1]}")
        assert len(tried) >= 4, tried  # the folders' titles at least: the search found controls
        click(dashboard, "STOP ARM")
        wait_text(dashboard, "Arm stopped — make sure the scene is safe")
        served.shutdown()
