"""The Chromium the browser tests start (support.browser.chromium): Playwright's own switches kept,
and no omnibox popup loaded, unseen, into each page's window."""

from __future__ import annotations

import psutil
import pytest
from support.browser import DISABLED_FEATURES, chromium, playwright_disabled_features, wait_function

pytestmark = [pytest.mark.browser]

SWITCH = "--disable-features="


def is_chromium(process: psutil.Process | None) -> bool:
    return process is not None and process.name().startswith("chromium")


def browser_command_line() -> list[str]:
    """The command line of the Chromium browser process this test process started: the one
    Chromium process whose parent is not Chromium (Playwright's driver started it). Its children
    (renderers, GPU, utilities, and a fork of its own in the instant before it runs another
    program, which still shows the browser's command line) are Chromium's."""
    browsers, seen = [], []
    for process in psutil.Process().children(recursive=True):
        try:
            if is_chromium(process):
                seen.append(process.cmdline())
                if not is_chromium(process.parent()):
                    browsers.append(seen[-1])
        except psutil.Error:  # a child that ended between the listing and the reading
            continue
    assert len(browsers) == 1, f"expected one Chromium browser process, saw {len(browsers)}: {seen}"
    return browsers[0]


def test_one_disable_features_switch_keeps_playwrights_and_drops_the_omnibox_popup():
    with chromium() as browser:
        lists = [word.removeprefix(SWITCH).split(",") for word in browser_command_line()
                 if word.startswith(SWITCH)]
        # Chromium keeps only the last switch: it names every feature of the earlier ones
        # (Playwright's), which the suite read from Playwright's driver, and the suite's own
        *earlier, last = lists
        assert earlier and all(set(named) <= set(last) for named in earlier), lists
        assert set().union(*earlier) == set(playwright_disabled_features())
        assert set(DISABLED_FEATURES) <= set(last)

        page = browser.new_context().new_page()
        page.goto("data:text/html,<title>suite-page</title>")
        # chrome://inspect lists the context's targets: its pages, and its windows' WebUIs
        targets = page.context.new_page()
        targets.goto("chrome://inspect/#other")
        wait_function(targets, "() => document.body.textContent.includes('suite-page')",
                      "chrome://inspect to list the context's page")
        assert "omnibox-popup" not in (targets.text_content("body") or "")
