"""The tablet as a kiosk in Chromium at a landscape tablet, a portrait tablet and a phone.

With five markers on the scale — the worst case, all five stacked as "equal" — the screen shows
none of viser's chrome, Confirm lies fully inside the window, the parts of the screen do not
overlap and neither do the stacked markers. When the server goes away, the whole screen asks the
participant to tell the experimenter. Screenshots (HANDOVER_DOC_FIGURES=1: to docs/figures/).
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    PAGE_POLL_S,
    button,
    chromium,
    confirm_placement,
    open_page,
    open_participant,
    pair_tablet,
    publish,
    run_trial,
    serve,
    shot,
    touch_drag_to,
    wait_function,
    wait_text,
)
from support.waiting import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: One batch of five placed handovers.
FIVE = ("initial_trials = 5\nbatch_size = 2\nlearning_batches = 0\nwithout_learning = true\n"
        "best_trials = 0\nvalidation_batches = 0\n")
SIZES = {"landscape": (1180, 820), "portrait": (820, 1180), "phone": (390, 844)}
#: viser's own chrome: panel handles and « arrow, header with the connection badge and the
#: settings gear, the settings themselves, notifications.
CHROME = ["[data-dock-region-handle]", "[data-dock-region-collapse]", "[data-dock-header]",
          "[data-dock-region-resize]", ".tabler-icon-adjustments", ".tabler-icon-cloud-check",
          ".mantine-Notification-root", "text=Connected", "text=Dev Settings", "text=Viser",
          "canvas"]
#: The parts of the scale screen, top to bottom.
PARTS = [".hl-title", ".hl-detail", ".hl-caption", ".hl-lane", ".hl-arrow", ".hl-ends",
         ".mantine-Slider-root"]


def layout_problems(page: Page, width: int, height: int) -> list[str]:
    """What is wrong with the scale screen's layout at ``width``×``height`` (nothing: [])."""
    problems = [f"{selector} is visible" for selector in CHROME
                for element in page.locator(selector).all() if element.is_visible()]
    boxes = [page.locator(selector).first.bounding_box() for selector in PARTS]
    boxes.append(button(page, "Confirm").bounding_box())
    if any(box is None for box in boxes):
        return [*problems, f"a part is not shown: {dict(zip([*PARTS, 'Confirm'], boxes, strict=True))}"]
    problems += [f"overlap: {upper} over {lower}" for upper, lower in pairwise(boxes)
                 if upper["y"] + upper["height"] > lower["y"] + 1]
    confirm = boxes[-1]
    if not (confirm["x"] >= 0 and confirm["x"] + confirm["width"] <= width
            and confirm["y"] >= 0 and confirm["y"] + confirm["height"] <= height):
        problems.append(f"Confirm cut off: {confirm}")
    lane = boxes[PARTS.index(".hl-lane")]
    markers = sorted((m.bounding_box() for m in page.locator(".hl-marker").all()),
                     key=lambda box: -box["y"])
    if len(markers) != 5:
        return [*problems, f"{len(markers)} markers, not 5"]
    problems += [f"markers overlap: {upper} over {lower}" for lower, upper in pairwise(markers)
                 if upper["y"] + upper["height"] > lower["y"] + 1]
    if not (lane["y"] - 1 <= markers[-1]["y"] and markers[0]["y"] + markers[0]["height"] <= (
            lane["y"] + lane["height"] + 1)):
        problems.append(f"markers outside the lane {lane}: {markers}")
    return problems


def check_layout(page: Page, width: int, height: int) -> None:
    """Wait until viser has laid the screen out for the new size (its mobile layout below 576 px
    comes a few frames after the resize) and it is right; if it never is, say what is wrong."""
    wait_for(lambda: not layout_problems(page, width, height), f"a right layout at {width}×{height}",
             seen=lambda: layout_problems(page, width, height), poll=PAGE_POLL_S)


def test_kiosk_layouts_with_five_markers_and_the_offline_cover(tmp_path: Path) -> None:
    """Slow: five markers need five handovers on the wall clock (each one driven from the dashboard
    and placed by touch), then three layouts are checked and shot, and the server is killed."""
    screens = tmp_path / "screens"
    with serve(tmp_path, protocol_toml=FIVE) as served, chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=(1400, 900))
        tablet = open_page(browser, served.tablet_url, touch=True, size=SIZES["landscape"])
        open_participant(dashboard, "P01")
        pair_tablet(dashboard, tablet)
        for label in range(1, 5):  # 1 at 0.3, then 2–4 dropped on it ("equal")
            assert run_trial(dashboard, tablet) == "place"
            touch_drag_to(tablet, 0.3)
            if label > 1:
                wait_text(tablet, "Same as 1")
            confirm_placement(tablet)
        assert run_trial(dashboard, tablet) == "place"
        touch_drag_to(tablet, 0.3)  # the fifth joins the stack: five markers in one column
        wait_text(tablet, "Same as 1")
        for name, (width, height) in SIZES.items():
            tablet.set_viewport_size({"width": width, "height": height})
            wait_function(tablet, f"() => window.innerWidth === {width}", f"the window {width} wide")
            check_layout(tablet, width, height)
            shot(tablet, screens, f"tablet-{name}-{width}x{height}")

        served.process.kill()  # the server dies: the whole screen asks for the experimenter
        served.process.wait()
        wait_function(tablet, "() => getComputedStyle(document.body, '::after').content"
                              ".includes('Please tell the experimenter')", "the offline cover")
        cover = tablet.evaluate("() => { const s = getComputedStyle(document.body, '::after');"
                                " return [s.position, s.width, s.height, s.backgroundColor]; }")
        assert cover == ["fixed", "390px", "844px", "rgb(255, 255, 255)"]
        shot(tablet, screens, "tablet-offline")
    publish([screens / f"tablet-{name}-{w}x{h}.png" for name, (w, h) in SIZES.items()]
            + [screens / "tablet-offline.png"])
