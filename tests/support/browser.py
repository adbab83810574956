"""Driving `handover serve` in headless Chromium (the Debian package) with Python Playwright.

The server runs as a real subprocess (real viser, real SQLite, real learner process); pages are real
browser pages. Touch drags are real touch events sent through the DevTools protocol
(``Input.dispatchTouchEvent``), the same path a finger on a tablet takes; taps are
``page.touchscreen.tap``. The tablet ignores input for ``SETTLE_S`` after each screen change
(app/ui/deliberate.py), so the participant's helpers let a screen settle before they touch it.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

from playwright.sync_api import Browser, Page, sync_playwright
from playwright.sync_api import Error as PlaywrightError

from app.protocol.vocabulary import QUESTIONS
from app.ui.deliberate import SETTLE_S

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--autoplay-policy=no-user-gesture-required"]
TOKEN = "test-token"
#: The short protocol of tests/support/engine.SHORT_PROTOCOL, as the [protocol] table of a lab config.
SHORT_TOML = ("initial_trials = 3\nbatch_size = 3\nlearning_batches = 1\nbest_trials = 1\n"
              "validation_batches = 1\n")
TIMEOUT_MS = 60_000
T = TypeVar("T")


SCREENS = {"unused": "not in use", "pair": "Connect this tablet", "pairs": "pairs of handovers",
           "back": "moving back", "place": "Handover",
           "wait": "Please wait", "rate": "Compared with", "done": "Thank you", "go": "Go!",
           **{q.id: q.text[:30] for q in QUESTIONS}}


def tablet_screen(page: Page, not_: str | tuple[str, ...] = (), timeout_s: float = 90.0,
                  unused_ok: bool = False) -> str:
    """Wait until the tablet shows a known screen other than ``not_`` (one name or several);
    return its name. "Not in use" counts only with ``unused_ok`` (a reloaded page is briefly the
    second page, until the server has seen the old one close)."""
    skip = {not_} if isinstance(not_, str) else set(not_)
    if not unused_ok:
        skip.update(("unused", "pair"))
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        text = page.inner_text("body")
        for name, marker in SCREENS.items():
            if marker in text and name not in skip:
                return name
        time.sleep(0.02)
    raise AssertionError(f"tablet shows no known screen: {page.inner_text('body')[:300]}")


def start_trial(dashboard: Page) -> None:
    """The experimenter's part of a trial's cycle: Start trial, Object loaded, then Go once the
    participant's hand rests at the start (each button waits until it is enabled)."""
    click(dashboard, "Start trial")
    click(dashboard, "Object loaded")
    click(dashboard, "Go")


def run_trial(dashboard: Page, tablet: Page) -> str:
    """Start trial, Object loaded and Go on the dashboard; the tablet shows "Go!", then the
    screen after the trial."""
    before = tablet_screen(tablet)  # "Please wait" or the introduction to the pairs
    start_trial(dashboard)
    assert tablet_screen(tablet, not_=before) == "go"
    return tablet_screen(tablet, not_=("go", "back"))  # the robot moves back, then the rating


def settle() -> None:
    """Let the screen just shown settle, as a participant reading it would (input earlier than
    SETTLE_S after a screen change is ignored by design)."""
    time.sleep(SETTLE_S + 0.1)


def double_tap(page: Page, name: str, gap_s: float = 0.15) -> None:
    """Two finger taps ``gap_s`` apart on the spot where button ``name`` is now (the second lands
    on whatever the first one brought up)."""
    point = tap_point(page, name)
    page.touchscreen.tap(*point)
    time.sleep(gap_s)
    page.touchscreen.tap(*point)


def answer_questionnaire(tablet: Page, answers: dict[str, str]) -> float:
    """Choose each question's answer (button text) and go on with Next, then Done; returns the
    seconds from the tap on Done until the tablet shows the screen after the questionnaire."""
    for i, q in enumerate(QUESTIONS):
        assert tablet_screen(tablet) == q.id
        settle()
        tap(tablet, answers[q.id])
        if i < len(QUESTIONS) - 1:
            tap(tablet, "Next")
            tablet_screen(tablet, not_=q.id)
    return timed_tap(tablet, "Done", QUESTIONS[-1].id)


def rate(tablet: Page, answer: str, folder: Path | None = None) -> float:
    """Choose a validation rating (screenshot ``tablet-rate`` into ``folder`` then) and Confirm
    it; seconds from the tap on Confirm to the next screen."""
    settle()
    tap(tablet, answer)
    if folder is not None:
        tablet.wait_for_function("() => [...document.querySelectorAll('button')].some("
                                 "b => !b.disabled && b.innerText.trim() === 'Confirm')")
        shot(tablet, folder, "tablet-rate")
    return timed_tap(tablet, "Confirm", "rate")


def confirm_placement(tablet: Page) -> float:
    """Tap Confirm on the scale; seconds until the tablet shows the next screen (the engine has
    stored the placement before it publishes the next state)."""
    point = tap_point(tablet, "Confirm")
    began = time.perf_counter()
    tablet.touchscreen.tap(*point)
    tablet.wait_for_function("() => !document.querySelector('.hl-scale')", polling="raf")
    return time.perf_counter() - began


def open_participant(dashboard: Page, code: str) -> None:
    """Unlock the dashboard if it is locked, then create or resume ``code``."""
    if "Enter the dashboard token" in dashboard.inner_text("body"):
        unlock_dashboard(dashboard)
    fill(dashboard, "Code", code)
    click(dashboard, "Create or resume")
    wait_text(dashboard, "handovers completed")


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@dataclass
class Served:
    process: subprocess.Popen
    tablet_url: str
    dashboard_url: str
    study: Path
    log: Path

    def shutdown(self, timeout: float = 30.0) -> str:
        """Ctrl-C, as the experimenter would; returns the server's output."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            self.process.wait(timeout)
        return self.log.read_text()


@contextmanager
def serve(tmp: Path, *extra: str, rate: int = 125, protocol_toml: str = SHORT_TOML,
          token: str | None = TOKEN, ports: tuple[int, int] | None = None,
          log_name: str = "serve.log", verbose: bool = False) -> Iterator[Served]:
    """`handover serve` on two free loopback ports (or ``ports``: tablet, dashboard) with a lab
    config of the short protocol (``protocol_toml`` is its [protocol] table) at ``rate`` Hz (125
    for speed); ``token`` None: the study's own dashboard token; its output in ``tmp/log_name``
    (``verbose``: at INFO level, every message the dashboard shows)."""
    config = tmp / "lab.toml"
    config.write_text(f"[loop]\nrate_hz = {rate}\n\n[protocol]\n{protocol_toml}")
    study, log = tmp / "study", tmp / log_name
    tablet, dashboard = ports or (free_port(), free_port())
    command = [sys.executable, "-m", "app.cli", *(["--verbose"] if verbose else []), "serve",
               "--study", str(study),
               "--tablet-port", str(tablet), "--dashboard-port", str(dashboard),
               "--config", str(config), *(["--token", token] if token else []), *extra]
    with log.open("w") as out:
        process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                   env={**os.environ, "PYTHONUNBUFFERED": "1"})
    served = Served(process, f"http://127.0.0.1:{tablet}", f"http://127.0.0.1:{dashboard}",
                    study, log)
    try:
        deadline = time.monotonic() + 60
        while "dashboard token" not in log.read_text():
            assert process.poll() is None, log.read_text()
            assert time.monotonic() < deadline, "server did not start"
            time.sleep(0.1)
        yield served
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


@contextmanager
def chromium() -> Iterator[Browser]:
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def open_page(browser: Browser, url: str, touch: bool = False,
              size: tuple[int, int] = (1024, 768)) -> Page:
    context = browser.new_context(viewport={"width": size[0], "height": size[1]},
                                  has_touch=touch, is_mobile=False)
    if not touch:  # the tablet hides viser's notices itself (app/ui/style.py, KIOSK_CSS)
        # Hide viser's "Software WebGL rendering detected" notice of headless Chromium (screenshots).
        context.add_init_script("document.addEventListener('DOMContentLoaded', () => {"
                            "const s = document.createElement('style');"
                            "s.textContent = '.mantine-Notification-root{display:none!important}';"
                            "document.head.appendChild(s); });")
    page = context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    page.goto(url)
    wait_ready(page)
    return page


def open_screens(browser: Browser, served: Served) -> tuple[Page, Page]:
    """The dashboard on a laptop-sized window (mouse), unlocked, and the tablet (touch), paired
    with the code the dashboard shows."""
    dashboard = open_page(browser, served.dashboard_url, size=(1400, 900))
    unlock_dashboard(dashboard)
    tablet = open_page(browser, served.tablet_url, touch=True)
    pair_tablet(dashboard, tablet)
    return dashboard, tablet


def pairing_code(dashboard: Page) -> str:
    """The tablet pairing code the (unlocked) dashboard shows."""
    wait_text(dashboard, "pairing code")
    return re.search(r"pairing code (\d{4})", dashboard.inner_text("body")).group(1)


def pair_tablet(dashboard: Page, tablet: Page) -> None:
    """Type the dashboard's pairing code on the tablet with the on-screen keyboard and tap Connect;
    wait until the tablet shows the study's screen."""
    wait_text(tablet, "Connect this tablet")
    settle()
    fill(tablet, "Code", pairing_code(dashboard))
    tap(tablet, "Connect")
    tablet_screen(tablet)


def wait_ready(page: Page) -> None:
    page.wait_for_function("() => document.body && document.body.innerText.length > 0 && "
                           "!document.body.innerText.includes('Connecting')")


def reload(page: Page) -> None:
    page.reload()
    wait_ready(page)


def wait_text(page: Page, text: str) -> None:
    page.get_by_text(text, exact=False).first.wait_for(state="visible")


def button(page: Page, name: str):
    return page.get_by_role("button", name=re.compile(f"^{re.escape(name)}$"))


def click(page: Page, name: str) -> None:
    button(page, name).click()  # waits until it is visible and enabled


def tap_point(page: Page, name: str, enabled: bool = True) -> tuple[float, float]:
    """The centre of button ``name`` once it is visible (and enabled, unless ``enabled`` is
    False: to tap a disabled button)."""
    target = button(page, name)
    target.wait_for(state="visible")
    if enabled:
        page.wait_for_function("b => !b.disabled", arg=target.element_handle())
    box = target.bounding_box()
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def tap(page: Page, name: str, enabled: bool = True) -> None:
    """A finger tap on a button (touch events, not mouse)."""
    page.touchscreen.tap(*tap_point(page, name, enabled))


def timed_tap(page: Page, name: str, screen: str) -> float:
    """Tap ``name`` and return the seconds until the tablet shows a screen other than ``screen``
    (the server has stored the answer before it publishes the next state)."""
    point = tap_point(page, name)
    began = time.perf_counter()
    page.touchscreen.tap(*point)
    tablet_screen(page, not_=screen)
    return time.perf_counter() - began


def labelled(page: Page, label: str):
    """The input labelled ``label`` (viser's labels are not <label> elements)."""
    return page.locator(f"xpath=//*[normalize-space(text())='{label}']/following::input[1]")


def fill(page: Page, label: str, value: str) -> None:
    """Type into the text field labelled ``label``."""
    labelled(page, label).fill(value)


def tick(page: Page, label: str, attempts: int = 3) -> None:
    """Tick the checkbox labelled ``label``. viser sets a box's state in the click's own event
    handler, so a click that leaves it unticked did not land on it (seen once in CI, on a loaded
    machine, right after a trial; not reproduced since). Such a click is tried again: ticking is
    idempotent, so a retry never unticks the box."""
    box = labelled(page, label)
    for attempt in range(attempts):
        try:
            box.check()
            return
        except PlaywrightError:
            if attempt == attempts - 1:
                raise


def unlock_dashboard(page: Page, token: str = TOKEN) -> None:
    fill(page, "Token", token)
    click(page, "Unlock")
    button(page, "STOP ARM").wait_for(state="visible")


def touch_drag_to(page: Page, fraction: float, steps: int = 12) -> None:
    """Drag the scale's handle (the slider thumb) with one finger to ``fraction`` of the track,
    once the screen has settled."""
    settle()
    track = page.locator(".mantine-Slider-track").first.bounding_box()
    thumb = page.locator(".mantine-Slider-thumb").first.bounding_box()
    y = thumb["y"] + thumb["height"] / 2
    x0 = thumb["x"] + thumb["width"] / 2
    x1 = track["x"] + fraction * track["width"]
    cdp = page.context.new_cdp_session(page)

    def touch(kind: str, x: float) -> None:
        points = [] if kind == "touchEnd" else [{"x": x, "y": y, "id": 1}]
        cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})

    touch("touchStart", x0)
    for i in range(1, steps + 1):
        touch("touchMove", x0 + (x1 - x0) * i / steps)
        time.sleep(0.01)
    # While the finger is down, no number is shown: no value label, no number box, no end marks.
    shown = page.evaluate("() => { const f = document.querySelector('.mantine-Slider-root')"
                          ".closest('.mantine-Flex-root'); const box = f.querySelector("
                          "'.mantine-NumberInput-root'); return [f.innerText, box ? "
                          "box.offsetParent !== null : false]; }")
    assert not re.search(r"\d", shown[0]) and not shown[1], f"a number shows while dragging: {shown}"
    touch("touchEnd", x1)
    cdp.detach()
    # The server redraws the newest marker where it received the handle: wait until it has.
    page.wait_for_function(
        "() => { const m = document.querySelector('.hl-new'); const t = document.querySelector("
        "'.mantine-Slider-thumb'); return m && t && Math.abs(parseFloat(m.style.left) - "
        "100 * parseFloat(t.getAttribute('aria-valuenow'))) < 0.05 || "
        "document.body.innerText.includes('Same as'); }")


def scale_value(page: Page) -> float:
    """The handle's position 0…1 as the slider reports it (aria-valuenow)."""
    return float(page.locator(".mantine-Slider-thumb").first.get_attribute("aria-valuenow"))


def shot(page: Page, folder: Path, name: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.png"
    page.screenshot(path=str(path))
    return path


DOC_FIGURES = Path(__file__).parents[2] / "docs" / "figures"


def publish(paths: list[Path]) -> None:
    """With HANDOVER_DOC_FIGURES=1, copy screenshots to docs/figures/ as ui-<name>.png."""
    if os.environ.get("HANDOVER_DOC_FIGURES") == "1":
        DOC_FIGURES.mkdir(exist_ok=True)
        for path in paths:
            shutil.copy(path, DOC_FIGURES / f"ui-{path.name}")


#: The dashboard's status line when the session waits for the experimenter's Start.
READY_TO_START = "Ready — press Start trial"


def keep_starting(dashboard: Page, done: Callable[[], T | None], timeout_s: float = 600.0) -> T:
    """The experimenter's part while the simulated participant rates: press Start trial each time
    the dashboard says the session is ready for it (once per time it says so), until ``done()``
    returns something, which is returned."""
    deadline = time.monotonic() + timeout_s
    pressed = False
    while (result := done()) is None:
        assert time.monotonic() < deadline, dashboard.inner_text("body")[:1000]
        ready = READY_TO_START in dashboard.inner_text("body")
        if ready and not pressed:
            click(dashboard, "Start trial")
        pressed = ready
        time.sleep(0.02)
    return result
