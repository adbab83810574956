"""The page each screen's browser loads (app/ui/client_page.py), in Chromium against real servers:
the study's title, the cover instead of viser's own screens on a page without its connection, pages
that come back by themselves after a restart although their window is not focused, paired and
unlocked without a code or a token (issue 37, items 4, 5 and 15), and a token (or a pairing code)
typed and confirmed at once, by click or by Enter (item 6); and the copy of viser's page, or
viser's own page with a warning when a later viser's page is not what the copy expects."""

from __future__ import annotations

import shutil
import urllib.request
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    TOKEN,
    chromium,
    labelled,
    open_page,
    open_screens,
    pairing_code,
    ports_of,
    serve,
    shot,
    tablet_screen,
    unlock_dashboard,
    wait_function,
    wait_text,
    wait_unlocked,
)

from app.ui.client_page import VISER_BUILD, client_folder
from app.ui.server import TABLET_PAGE
from app.ui.style import COVER_DELAY_S

SHOTS = Path("/tmp/tablet-shots")
#: A window without the focus, as viser's client asks it (it retries a lost connection only while
#: ``document.hasFocus()``): set in the page now and in every page the context loads from now on.
UNFOCUSED_JS = "Document.prototype.hasFocus = function () { return false; };"
#: The text of the page's cover (the ::after of its body), and whether it is shown (opaque).
COVER_JS = """() => { const s = getComputedStyle(document.body, '::after');
  return s.content !== 'none' && s.opacity === '1' ? s.content : ''; }"""
#: What a finger would touch at 25 points across the page: only the body (its cover, drawn over
#: everything) or the first element found above it.
COVERED_JS = """() => { for (let i = 0; i < 5; i++) for (let j = 0; j < 5; j++) {
    const e = document.elementFromPoint((i + 0.5) * innerWidth / 5, (j + 0.5) * innerHeight / 5);
    if (e !== document.body && e !== document.documentElement) return e.outerHTML.slice(0, 80);
  } return 'the cover'; }"""


def unfocus(page: Page) -> None:
    page.context.add_init_script(UNFOCUSED_JS)
    page.evaluate(f"() => {{ {UNFOCUSED_JS} }}")
    assert page.evaluate("() => document.hasFocus()") is False


def assert_covered(page: Page, says: str) -> None:
    """The page shows the project's cover saying ``says``, and nothing of viser's own page can be
    seen or touched."""
    wait_function(page, f"() => ({COVER_JS})().includes({says!r})",
                  f"the cover saying {says!r} (after {COVER_DELAY_S} s without a screen)")
    assert page.evaluate(COVERED_JS) == "the cover"


@pytest.mark.browser
def test_a_restart_brings_the_pages_back_unfocused_paired_and_unlocked(tmp_path: Path) -> None:
    """Both pages lose the server, their windows not focused; the tablet is reloaded while the
    server is down (its page from the browser's cache: here, Playwright's route answers with the
    page the server served); a new server of the same study comes up on the same ports. Before,
    viser's page showed its own "Inactive" panel and editable ws:// address on the reloaded tablet,
    an unfocused page never retried, the tablet asked for a new pairing code and the dashboard for
    the token again; the tab said "Viser"."""
    with chromium() as browser:
        with serve(tmp_path) as served:
            dashboard, tablet = open_screens(browser, served)
            assert tablet_screen(tablet) == "wait"
            page_html = urllib.request.urlopen(served.tablet_url).read()
            for page in (tablet, dashboard):
                unfocus(page)
            ports = ports_of(served)
            served.shutdown()
        assert_covered(tablet, "The tablet has lost its connection")
        assert_covered(dashboard, "SERVER UNREACHABLE")
        tablet.route(f"{served.tablet_url}/", lambda route: route.fulfill(
            status=200, content_type="text/html", body=page_html))
        tablet.reload(wait_until="domcontentloaded")
        tablet.unroute_all()
        assert_covered(tablet, "The tablet has lost its connection")
        shot(tablet, SHOTS, "tablet-reloaded-while-down")
        with serve(tmp_path, ports=ports, log_name="serve-again.log") as again:
            assert tablet_screen(tablet) == "wait"  # paired without the code
            wait_unlocked(dashboard)  # unlocked without the token
            assert tablet.evaluate("() => document.hasFocus()") is False
            assert tablet.title() == "Handover study"
            assert dashboard.title() == "handover-lab dashboard"
            shot(tablet, SHOTS, "tablet-back-after-restart")
            shot(dashboard, SHOTS, "dashboard-back-after-restart")
            output = again.shutdown()
    assert "tablet paired again" in output
    assert "wrong token" not in output and "token accepted" not in output  # no token was typed


@pytest.mark.browser
def test_a_token_confirmed_at_once_by_click_or_enter_unlocks(tmp_path: Path) -> None:
    """A token pasted and Unlock clicked at once, or typed and Unlock clicked at once, reached the
    server as the old value ("Wrong token.", counted as a failed attempt): viser's client sends a
    text field's value through a throttled sender that loses it when the click follows within
    50 ms. Enter did nothing. Each way here is a fresh browser (a fresh context)."""
    with serve(tmp_path) as served, chromium() as browser:
        ways = {"paste, then click at once": "paste-click", "type, then click at once": "type-click",
                "type, then Enter": "type-enter"}
        for way in ways.values():
            page = open_page(browser, served.dashboard_url, size=(1400, 900))
            field = labelled(page, "Token")
            field.click()
            # where Unlock is once the field has the focus (focusing it may scroll the panel)
            unlock = page.get_by_role("button", name="Unlock").bounding_box()
            if way.startswith("paste"):
                page.keyboard.insert_text(TOKEN)  # one input event, as a paste
            else:
                page.keyboard.type(TOKEN)
            if way.endswith("enter"):
                page.keyboard.press("Enter")
            else:
                page.mouse.click(unlock["x"] + unlock["width"] / 2,
                                 unlock["y"] + unlock["height"] / 2)
            wait_unlocked(page)
            page.context.close()
        dashboard = open_page(browser, served.dashboard_url, size=(1400, 900))
        unlock_dashboard(dashboard)
        tablet = open_page(browser, served.tablet_url, touch=True)
        wait_text(tablet, "Connect this tablet")
        code = pairing_code(dashboard)
        labelled(tablet, "Code").click()
        tablet.keyboard.type(code)
        tablet.keyboard.press("Enter")
        assert tablet_screen(tablet) == "wait"
        output = served.shutdown()
    assert output.count("dashboard: token accepted") == 4
    assert "wrong token" not in output and "wrong code" not in output


def test_the_page_is_a_copy_of_visers_with_the_studys_head(tmp_path: Path) -> None:
    folder = client_folder(TABLET_PAGE)
    try:
        page, original = (folder / "index.html").read_text(), (VISER_BUILD / "index.html").read_text()
        assert "<title>Handover study</title>" in page and "<title>Viser</title>" not in page
        assert "<script" not in page[:page.index(TABLET_PAGE.head())]  # ours runs before viser's
        assert page.replace(TABLET_PAGE.head(), "<title>Viser</title>") == original
    finally:
        shutil.rmtree(folder)


def test_a_later_visers_page_without_a_title_falls_back_to_its_own(tmp_path: Path, caplog) -> None:
    build = tmp_path / "build"
    build.mkdir()
    (build / "index.html").write_text("<html><head><script>viser()</script></head></html>")
    assert client_folder(TABLET_PAGE, build) is None
    assert "the screens use viser's own page" in caplog.text


@pytest.mark.browser
def test_another_browser_needs_the_code_after_the_tablets_page_closed(tmp_path: Path) -> None:
    """After the paired tablet's page closed, another browser from the same address became the
    tablet without the code, while the dashboard advised typing a code the tablet did not need
    (issue 45, item 11). Two browsers here (two contexts: two cookie jars) on one address."""
    with serve(tmp_path) as served, chromium() as browser:
        dashboard, tablet = open_screens(browser, served)
        assert tablet_screen(tablet) == "wait"
        paired = tablet.context
        tablet.close()
        wait_text(dashboard, "the paired tablet's page is closed: open the tablet page on it again "
                             "(no code needed")
        shot(dashboard, SHOTS, "dashboard-tablet-page-closed")
        other = open_page(browser, served.tablet_url, touch=True)  # the same address, 127.0.0.1
        wait_text(other, "Connect this tablet")
        wait_text(dashboard, "the tablet is not paired: type the code")
        shot(other, SHOTS, "tablet-another-browser-same-address")
        other.close()
        again = paired.new_page()  # the tablet's own browser: no code
        again.goto(served.tablet_url)
        assert tablet_screen(again) == "wait"
        served.shutdown()
