"""The experimenter's dashboard, safety first, in headless Chromium against `handover serve`.

* Start is refused while no tablet is paired; the reason stands beside it; the tablet pairs with the
  code the dashboard shows (typed with touch), and Start is allowed.
* STOP ARM is in the viewport after the panel is scrolled to its end at 1366×768, and Esc stops
  the arm while it holds the object out at H (the simulated participant never takes it, so the
  hold lasts until the stop); after the stop, Start stays refused until Re-arm (the stop's state is
  shown). A stop while the arm moves on its reach: tests/robot_io/control/test_loop.py
  (``test_real_clock_worker_thread_stops_on_request``) and tests/session/test_rehearsal.py (the rig
  killed mid-reach).
* Two participants run one after the other in one server process (End session, then create the
  next), and the study overview lists both.
* A restart keeps the dashboard token (stored with the study); while the server is down the page
  shows the unreachable banner.

Screenshots are written to the test's tmp folder.
"""

from __future__ import annotations

import re
import signal
from pathlib import Path

import pytest
from playwright.sync_api import Page
from support.browser import (
    BRIEF_TOML,
    NEVER_TAKES,
    button,
    chromium,
    click,
    in_viewport,
    keep_starting,
    open_folder,
    open_page,
    open_participant,
    pair_tablet,
    ports_of,
    serve,
    shot,
    tablet_screen,
    tick,
    unlock_dashboard,
    wait_enabled,
    wait_function,
    wait_gone,
    wait_ready,
    wait_text,
    wait_unlocked,
)

from session_store.store import ParticipantStore

pytestmark = [pytest.mark.browser, pytest.mark.slow]

LAPTOP = (1366, 768)


def scroll_panel_to_end(page: Page) -> None:
    """Scroll every scrollable container of the page (the main panel) to its end, until each is
    there in one frame. The panel grows while it is scrolled (an event line, a plot drawn): one
    scroll, then a wait, left a container short of an end that had moved on (CI, twice)."""
    scrollables = """[...document.querySelectorAll('*')].filter(e => e.scrollHeight > e.clientHeight + 4
        && ['auto', 'scroll'].includes(getComputedStyle(e).overflowY))"""
    wait_function(page, f"""() => {{ const all = {scrollables};
        for (const e of all) e.scrollTo({{top: e.scrollHeight, behavior: 'instant'}});
        return all.every(e => e.scrollTop + e.clientHeight >= e.scrollHeight - 4); }}""",
                  "every scrollable container at its end")


def start_refused_because(dashboard: Page, reason: str) -> None:
    wait_text(dashboard, f"Start is locked: {reason}")
    assert button(dashboard, "Start trial").is_disabled()


def test_tablet_pairing_stop_rearm_and_a_pinned_stop(tmp_path: Path) -> None:
    """Slow: `handover serve` and Chromium start, and the trial that the stop ends runs on the wall
    clock up to the arm's hold at H before the stop can be pressed there."""
    screens = tmp_path / "screens"
    # The participant never takes the object: the trial's hold lasts until the experimenter's stop.
    with serve(tmp_path, tables=NEVER_TAKES) as served, chromium() as browser:
        dashboard = open_page(browser, served.dashboard_url, size=LAPTOP)
        open_participant(dashboard, "P01")
        start_refused_because(dashboard, "no tablet is connected")
        wait_text(dashboard, "Ready, but no tablet is connected")
        shot(dashboard, screens, "dashboard-no-tablet")

        # The panel scrolled to its end: STOP ARM is still fully in view, on top of everything.
        open_folder(dashboard, "Learner")
        scroll_panel_to_end(dashboard)
        assert in_viewport(dashboard, "STOP ARM")
        shot(dashboard, screens, "dashboard-scrolled-to-end")

        # A page on the tablet port is offered only the pairing code until it types it.
        tablet = open_page(browser, served.tablet_url, touch=True, size=(1180, 820))
        assert tablet_screen(tablet, unused_ok=True) == "pair"
        assert tablet.locator(".mantine-Slider-root, .hl-scale").count() == 0
        start_refused_because(dashboard, "the tablet is not paired")
        shot(tablet, screens, "tablet-pair")
        pair_tablet(dashboard, tablet)
        wait_text(dashboard, "Tablet: connected and paired")
        assert tablet_screen(tablet) == "wait"
        wait_enabled(dashboard, "Start trial")
        wait_gone(dashboard, "Start is locked")  # its reason is sent after the button's state

        # STOP by its key while the arm holds the object out at H (the hold lasts until the stop:
        # nobody takes the object): the trial is stopped, Start locked until Re-arm.
        click(dashboard, "Start trial")
        click(dashboard, "Object loaded")
        click(dashboard, "Go")
        wait_text(dashboard, "[hold]")
        dashboard.locator("body").click(position={"x": 200, "y": 300})  # focus on the page
        dashboard.keyboard.press("Escape")
        wait_text(dashboard, "Arm: STOPPED")
        wait_text(dashboard, "stopped by the experimenter (Stop)")
        assert tablet_screen(tablet, not_="go") == "wait"
        start_refused_because(dashboard, "the arm was stopped")
        wait_text(dashboard, "make sure the scene is safe, then press Re-arm")
        shot(dashboard, screens, "dashboard-stopped")
        # A watch for something that must not happen (Start unlocking by itself), not a wait for a
        # state: load can only make the watch see fewer refreshes, never fail a locked Start.
        dashboard.wait_for_timeout(1000)
        assert button(dashboard, "Start trial").is_disabled()  # still locked: nobody re-armed
        click(dashboard, "Re-arm (scene is safe)")
        wait_text(dashboard, "Arm: armed")
        wait_enabled(dashboard, "Start trial")

        # A second page on the paired tablet (a second tab of its browser) is not offered the scale.
        second = tablet.context.new_page()
        second.goto(served.tablet_url)
        wait_ready(second)
        assert tablet_screen(second, unused_ok=True) == "unused"
        start_refused_because(dashboard, "2 pages are open on the tablet port")
        second.close()
        wait_enabled(dashboard, "Start trial")
        served.shutdown()
    store = ParticipantStore.open(served.study, "P01")
    try:
        [trial] = store.rows("trials")
        stages = [e.payload["stage"] for e in store.events() if e.kind == "trial_stage"]
    finally:
        store.close()
    assert trial.outcome.value == "aborted" and trial.reason == "stopped by the experimenter (Stop)"
    # stopped in the hold: neither released nor timed out (not_taken), and never retracted
    assert stages == ["prepare", "loaded", "ready", "go", "reach", "hold"], stages


def run_participant(dashboard: Page, code: str) -> None:
    """Create ``code`` and run its whole protocol with the simulated participant rating;
    the experimenter presses Start for every trial."""
    open_participant(dashboard, code)
    tick(dashboard, "Simulated participant rates", "simulated participant on")
    keep_starting(dashboard, lambda: "Session complete" in dashboard.inner_text("body") or None)


def test_two_participants_in_one_server_and_the_token_kept(tmp_path: Path) -> None:
    """Slow because it is the whole story: two participants' sessions of 3 handovers each on the wall
    clock, one after the other in one `handover serve`, then the server SIGKILLed and started again
    (a second start-up, torch and the rig included) for the page to reconnect by itself."""
    screens = tmp_path / "screens"
    with serve(tmp_path, token=None, protocol_toml=BRIEF_TOML) as served, chromium() as browser:
        token = re.search(r"dashboard token:\s+(\S+)", served.log.read_text()).group(1)
        dashboard = open_page(browser, served.dashboard_url, size=LAPTOP)
        unlock_dashboard(dashboard, token)
        tablet = open_page(browser, served.tablet_url, touch=True, size=(1180, 820))
        pair_tablet(dashboard, tablet)
        run_participant(dashboard, "P01")
        click(dashboard, "End session")
        wait_text(dashboard, "No participant open")
        run_participant(dashboard, "P02")
        click(dashboard, "End session")
        wait_text(dashboard, "No participant open")
        rows = dashboard.locator("table").first.inner_text()
        assert re.search(r"P01\s+straightforward\s+3 of 3\s+complete", rows), rows
        assert re.search(r"P02\s+straightforward\s+3 of 3\s+complete", rows), rows
        shot(dashboard, screens, "dashboard-overview")
        ports = ports_of(served)  # the restart binds the same ports: the open page reconnects
        served.process.send_signal(signal.SIGKILL)  # the server dies: the page says so
        served.process.wait(10)
        wait_function(dashboard, "() => getComputedStyle(document.body, '::after').content"
                                 ".includes('SERVER UNREACHABLE')", "the unreachable banner")
        shot(dashboard, screens, "dashboard-unreachable")
        with serve(tmp_path, token=None, protocol_toml=BRIEF_TOML, ports=ports) as again:
            assert re.search(r"dashboard token:\s+(\S+)", again.log.read_text()).group(1) == token
            wait_ready(dashboard)  # the same page reconnects by itself
            wait_function(dashboard, "() => !getComputedStyle(document.body, '::after').content"
                                     ".includes('UNREACHABLE')", "the unreachable banner to go")
            wait_unlocked(dashboard)  # this browser was unlocked before the kill: no token again
            wait_text(dashboard, "P02")
            again.shutdown()
    for code in ("P01", "P02"):
        store = ParticipantStore.open(served.study, code)
        try:
            trials = store.rows("trials")
        finally:
            store.close()
        assert sum(t.outcome.value == "completed" for t in trials) == 3
    assert (served.study / ".dashboard-token").read_text().strip() == token
