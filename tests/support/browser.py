"""Driving `handover serve` in headless Chromium (the Debian package) with Python Playwright.

The server runs as a real subprocess (real viser, real SQLite, real learner process); pages are real
browser pages. Touch drags are real touch events sent through the DevTools protocol
(``Input.dispatchTouchEvent``), the same path a finger on a tablet takes; taps are
``page.touchscreen.tap``. The tablet ignores input for ``SETTLE_S`` after each screen change
(app/ui/deliberate.py), so the participant's helpers let a screen settle before they touch it.

Every helper waits for a state and, when it gives up, says what the page showed (its text) and, for a
page of a server started by :func:`serve`, the end of the server's log. The servers bind port 0 (any
free port) and the helpers read the ports bound from the server's output: two suites, or two xdist
workers, never race for a guessed port.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import playwright
import viser
from playwright.sync_api import Browser, ConsoleMessage, Page, sync_playwright
from playwright.sync_api import Error as PlaywrightError
from viser import _messages

from app.ui.deliberate import SETTLE_S
from app.ui.participant_form import CHOOSE
from app.ui.style import DISCONNECTED
from session_store.vocabulary import QUESTIONS
from support.engine import BRIEF_PROTOCOL, SHORT_PROTOCOL, protocol_toml
from support.runner import READY_CEILING_S
from support.waiting import CEILING_S, tail, wait_for

CHROMIUM = "/usr/bin/chromium"
#: Chromium features the suite turns off beside Playwright's own list: the omnibox's suggestion popup
#: as a WebUI. Headless Chromium loads it, unseen, into every window it opens (each page of the suite
#: is a window of its own context): chrome://omnibox-popup.top-chrome/ and its AI-mode page, about
#: 0.7 CPU-seconds of a renderer and 0.2 of the browser process per page opened (benchmarks/
#: browser_pages.py). The pages under test do not change.
DISABLED_FEATURES = ("WebUIOmniboxPopup", "WebUIOmniboxAimPopup")
#: Where Playwright's driver keeps the switches it starts Chromium with (its bundle, or before it
#: the module of its own).
PLAYWRIGHT_SWITCHES = ("lib/coreBundle.js", "lib/server/chromium/chromiumSwitches.js")


@functools.cache
def playwright_disabled_features() -> tuple[str, ...]:
    """The features Playwright's driver disables when it starts Chromium (its ``disabledFeatures``).

    Chromium keeps only the last ``--disable-features`` of its command line: a list of the suite's
    own, passed after Playwright's, would turn Playwright's back on (``PaintHolding`` among them).
    So the suite passes both in one switch. Empty when the driver's file is not found or says no
    such list: the suite then passes nothing of its own (tests/ui/test_chromium.py fails). Read once
    a process (the driver's bundle is ~3.6 MB), not at every Chromium start."""
    driver = Path(playwright.__file__).parent / "driver" / "package"
    for name in PLAYWRIGHT_SWITCHES:
        if (path := driver / name).is_file() and (
                found := re.search(r"disabledFeatures = \[(.*?)\]", path.read_text(), re.DOTALL)):
            return tuple(re.findall(r'^\s*"(\w+)",?\s*$', found.group(1), re.MULTILINE))
    return ()


def chromium_args() -> list[str]:
    """The command line the suite adds to Playwright's when it starts Chromium."""
    playwrights = playwright_disabled_features()
    features = [f"--disable-features={','.join([*playwrights, *DISABLED_FEATURES])}"] if playwrights else []
    return ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--autoplay-policy=no-user-gesture-required", *features]


TOKEN = "test-token"
#: How often a wait here reads a page [s]. A look at a page is a round trip through Playwright's
#: driver and a layout of the page in Chromium: at the suite's 0.02 s (support/waiting.POLL_S) the
#: looks of a tablet test took 12 of its 58 CPU-seconds (test_tablet_session, alone). A state a page
#: shows stays shown for longer than this; waits that sample passing states poll faster themselves.
PAGE_POLL_S = 0.1
#: The short and the briefest protocol of tests/support/engine, as [protocol] tables of a lab config.
SHORT_TOML = protocol_toml(SHORT_PROTOCOL)
BRIEF_TOML = protocol_toml(BRIEF_PROTOCOL)
#: Lab-config tables of a simulated participant who never takes the object (robot_io.hands.simulated_pull:
#: ``pull_n = 0``): once the arm holds the object out at H, the trial stays in its hold until the
#: experimenter acts. Only [release] timeout_s (here its largest value, 60 s) of holding would end it
#: (``not_taken``): as long as Playwright's ceiling for any one action (TIMEOUT_MS), so a stop that
#: misses the hold is an action slower than the suite allows, and the test says the trial ended
#: not_taken. The session keeps these tables for every trial of a participant it creates.
NEVER_TAKES = "[hand]\npull_n = 0.0\n\n[release]\ntimeout_s = 60.0\n"
#: Playwright's ceiling for one wait (a locator, a function): far above what a state takes on a
#: loaded 2-core machine; a timeout is re-raised by :func:`awaiting` with what the page showed.
TIMEOUT_MS = 60_000
#: Playwright's ceiling for a button that waits on the learner to become enabled: the session
#: plans each interaction's θ before it enables Start trial, and the planner waits up to
#: PLAN_TIMEOUT_S for the learner, then falls back to a flagged Sobol point (app/session/runner.py),
#: so Start comes within that however slow the learner (support.runner.READY_CEILING_S). (A
#: session's first learner imports torch and fits first: with two suites on two cores it took more
#: than TIMEOUT_MS, and the test gave up on a page that said "Preparing the next handover".)
LEARNER_CEILING_MS = READY_CEILING_S * 1000
#: The buttons enabled only once the learner has answered, and their ceilings.
CEILINGS_MS = {"Start trial": LEARNER_CEILING_MS}
#: How much of a page's text a failure shows.
PAGE_CHARS = 3000
T = TypeVar("T")

#: The output of each server :func:`serve` runs now in this process, by its URLs (for failures).
_LOGS: dict[str, Path] = {}
#: What each page :func:`open_page` opened reported (for failures): its uncaught exceptions, its
#: console errors and warnings, and viser's own notices below. An exception thrown in a frame of
#: viser's render loop drops the rest of the batch of messages it was applying; a reconnection
#: shows as a second "Connected!"; either way a page can show stale text while its own animation
#: frames still run.
_NOTICES: weakref.WeakKeyDictionary[Page, list[str]] = weakref.WeakKeyDictionary()
#: What viser's client (its page and its websocket worker) logs about its connection and its
#: messages: connected, disconnected, a message it could not send, a message it could not order.
VISER_NOTICES = ("Connected!", "Disconnected!", "Tried to send", "Order lock timed out",
                 "Received message did not match")
#: The in-process viser client of a page, where a test said (:func:`watch_client`).
_CLIENTS: weakref.WeakKeyDictionary[Page, viser.ClientHandle] = weakref.WeakKeyDictionary()
#: Warnings every page logs, never a cause: software WebGL's driver notes, three.js deprecations.
ROUTINE_WARNINGS = ("[.WebGL-", "THREE.")
#: How many of a page's notices a failure shows (the latest).
NOTICES_SHOWN = 8


def notable(message: ConsoleMessage) -> bool:
    """A console message worth a failure's mention: an error, a warning but the routine ones, or
    one of viser's notices."""
    return (message.type == "error" or message.text.startswith(VISER_NOTICES)
            or (message.type == "warning" and not message.text.startswith(ROUTINE_WARNINGS)))


def page_text(page: Page) -> str:
    """What the page shows (its first PAGE_CHARS characters), for a failure's message."""
    try:
        # A live page answers at once; 5 s keeps a failure's message from waiting a minute more
        # on a page that is gone or hung (which the message then says).
        return repr(page.inner_text("body", timeout=5_000)[:PAGE_CHARS])
    except PlaywrightError as exc:  # a closed page, a page between loads: say so
        return f"<page text unreadable: {str(exc).splitlines()[0]}>"


#: Read in a page by :func:`page_state` at its third animation frame: whether viser shows the page
#: as disconnected (its dimmed, input-blocking gate around the screen's ``.hl-live`` marker, over
#: which app/ui/style.offline_cover draws) and whether the page has the focus (viser retries a
#: lost connection only while it has).
PAGE_STATE_JS = f"""() => (window.__hlFrames = (window.__hlFrames || 0) + 1) > 2 && [
  document.querySelector({DISCONNECTED!r}) ? 'disconnected' : 'connected',
  document.hasFocus() ? 'focused' : 'not focused']"""


#: Read in a page by :func:`page_state`: how many messages viser's client holds in its queue, the
#: first kinds, and its render request state (found through React's fiber tree: the value of the
#: context provider that holds viser's mutable viewer state). The queue drains in a frame of the
#: render loop, or at once for a batch that touches only the GUI when nothing waits before it.
PAGE_QUEUE_JS = """() => {
  const root = document.getElementById('root');
  const key = root && Object.keys(root).find(k => k.startsWith('__reactContainer$'));
  if (!key) return 'no React root';
  const fibers = [root[key]];
  for (let looked = 0; fibers.length && looked < 500000; looked++) {
    const fiber = fibers.pop();
    const value = fiber.memoizedProps && fiber.memoizedProps.value;
    const viewer = value && value.mutable && value.mutable.current;
    if (viewer && Array.isArray(viewer.messageQueue)) {
      const queue = viewer.messageQueue;
      return `${queue.length} messages queued` + (queue.length ? ` (the first: ${
        queue.slice(0, 3).map(m => m.type).join(', ')})` : '') +
        `, render request ${viewer.getRenderRequestState}`;
    }
    if (fiber.child) fibers.push(fiber.child);
    if (fiber.sibling) fibers.push(fiber.sibling);
  }
  return "viser's viewer state not found";
}"""
#: Installed in every page :func:`open_page` opens, before viser's own scripts, and read by
#: :func:`gui_input` for a failure's message: where each press, release and click landed (the
#: button or element, its text), and the GUI input (clicks, values) the page handed to viser's
#: websocket worker, as (ms since load, kind, element uuid, what). viser's panel sends its input
#: through a sender throttled at 50 ms that keeps only the last of a burst and drops what it holds if
#: its panel unmounts: this shows whether a click reached its button and left the page at all.
GUI_INPUT_JS = """(() => {
  const sent = window.__hlGuiSent = [];
  const post = Worker.prototype.postMessage;
  Worker.prototype.postMessage = function (data, ...rest) {
    const m = data && data.type === 'send' && data.message;
    if (m && m.type.startsWith('Gui')) {
      sent.push([Math.round(performance.now()), m.type, m.uuid || '',
                 JSON.stringify(m.updates ?? '').slice(0, 60)]);
      if (sent.length > 100) sent.splice(0, 50);
    }
    return post.call(this, data, ...rest);
  };
  const pointer = window.__hlPointer = [];
  for (const kind of ['pointerdown', 'pointerup', 'click']) {
    window.addEventListener(kind, (event) => {
      const on = event.target instanceof Element ? event.target.closest('button') || event.target : null;
      pointer.push([Math.round(performance.now()), kind, on ? on.tagName.toLowerCase() + ' '
                    + JSON.stringify((on.innerText || '').trim().slice(0, 30)) : String(event.target)]);
      if (pointer.length > 100) pointer.splice(0, 50);
    }, true);
  }
})();"""
#: How many of a page's sent and received GUI inputs a failure shows (the latest).
INPUTS_SHOWN = 6
#: The GUI input each watched page's server received (:func:`watch_client`), as (monotonic time,
#: element uuid, what, the element's label or "gone" for one the server has removed).
_RECEIVED: weakref.WeakKeyDictionary[Page, list[tuple]] = weakref.WeakKeyDictionary()
#: How long :func:`page_state` watches viser's queue [ms]: longer than viser's 1 s render
#: heartbeat, so a queue still waiting after it waits on a render loop that has stopped. (A look
#: for a failure's message only, never a wait for a state.)
QUEUE_WATCH_MS = 1_500


def page_state(page: Page) -> str:
    """Whether the page still runs animation frames, is connected and has the focus, and what it
    reported (:data:`_NOTICES`), for a failure's message: viser applies every batch of messages that
    touches its scene (the live view's), and the GUI messages queued behind it, in a frame of its
    render loop, and keeps the last screen of a lost connection; either way a page shows stale
    text."""
    try:  # the first look may come at once, the next two come with animation frames
        state = page.wait_for_function(PAGE_STATE_JS, polling="raf", timeout=2_000).json_value()
        shown = ", ".join(["animation frames running", *state])
    except PlaywrightError as exc:
        shown = f"no animation frames within 2 s: {str(exc).splitlines()[0]}"
    try:
        first = page.evaluate(PAGE_QUEUE_JS)
        page.wait_for_timeout(QUEUE_WATCH_MS)
        shown += f"; viser's queue: {first}, {QUEUE_WATCH_MS} ms later {page.evaluate(PAGE_QUEUE_JS)}"
    except PlaywrightError as exc:
        shown += f"; viser's queue unreadable: {str(exc).splitlines()[0]}"
    notices = _NOTICES.get(page, [])
    return shown + (f"; {len(notices)} page notices, the latest: " + " | ".join(notices[-NOTICES_SHOWN:])
                    if notices else "; no page notices")


def server_tail(page: Page) -> str:
    """The end of the log of the server that served ``page``, if :func:`serve` started it."""
    for url, log in list(_LOGS.items()):
        if page.url.startswith(url):
            try:
                return tail(log.read_text())
            except OSError as exc:
                return f"<{log} unreadable: {exc}>"
    return ""


def sending(client: viser.ClientHandle) -> str:
    """What viser's server holds for one client's page and has not handed to its websocket yet,
    for a failure's message: the messages queued past the page's cursor, and whether an atomic
    block holds them back (viser's message buffer, read from its private state: no public API
    says this)."""
    buffer = client._websock_connection.get_message_buffer()
    cursor = buffer.generator_cursors.get(client.client_id)
    waiting = "no sender" if cursor is None else f"{buffer.message_counter - 1 - cursor} messages"
    return (f"server to client {client.client_id}: {waiting} not yet sent, atomic depth "
            f"{buffer.atomic_counter}{', closed' if buffer.done else ''}")


def watch_client(page: Page, client: viser.ClientHandle) -> None:
    """Let a failure on ``page`` say what its in-process server still holds for it (:func:`sending`)
    and what GUI input it received from it (its connection's own handler hook, beside viser's)."""
    _CLIENTS[page] = client
    received = _RECEIVED.setdefault(page, [])

    def record(client_id: int, message: _messages.GuiUpdateMessage) -> None:
        handle = client.gui._gui_input_handle_from_uuid.get(message.uuid)
        label = "gone" if handle is None or handle._impl.removed else repr(handle.label)
        received.append((time.monotonic(), message.uuid, str(message.updates)[:60], label))
        del received[:-INPUTS_SHOWN]

    client._websock_connection.register_handler(_messages.GuiUpdateMessage, record)


def gui_input(page: Page) -> str:
    """The latest GUI input the page sent and, for a watched page, what its server received, for a
    failure's message (a click that never left the page, or one the server dropped)."""
    try:
        sent, pointer = page.evaluate("() => [window.__hlGuiSent || [], window.__hlPointer || []]")
        sent, pointer = sent[-INPUTS_SHOWN:], pointer[-3 * INPUTS_SHOWN:]
    except PlaywrightError as exc:
        sent = pointer = f"<unreadable: {str(exc).splitlines()[0]}>"
    shown = f"the page's presses (ms, event, on): {pointer}; it sent (ms, kind, uuid, updates): {sent}"
    if page in _RECEIVED:
        now = time.monotonic()
        shown += ("; its server received (s ago, uuid, updates, element): "
                  f"{[(round(now - t, 2), *rest) for t, *rest in _RECEIVED[page]]}")
    return shown


def what_it_showed(page: Page) -> str:
    """The page's text, what the page's client reported and holds, and, when known, its server's
    log tail or what its in-process server still holds for it, for a failure's message."""
    log = server_tail(page)
    client = _CLIENTS.get(page)
    return (f"the page showed: {page_text(page)} ({page_state(page)}); {gui_input(page)}"
            + (f"; {sending(client)}" if client is not None else "")
            + (f"\nserver log tail:\n{log}" if log else ""))


@contextmanager
def awaiting(page: Page, what: str) -> Iterator[None]:
    """Re-raise a Playwright timeout (or a wait cut short) inside as an AssertionError naming
    ``what`` was awaited and what the page showed instead."""
    try:
        yield
    except PlaywrightError as exc:
        raise AssertionError(f"{what}: {str(exc).splitlines()[0]}\n{what_it_showed(page)}") from exc


def wait_function(page: Page, script: str, what: str, arg: object = None, polling: str = "raf",
                  timeout_ms: float = TIMEOUT_MS) -> None:
    """``page.wait_for_function`` for the state ``what``; a timeout says what the page showed."""
    with awaiting(page, f"waiting for {what}"):
        page.wait_for_function(script, arg=arg, polling=polling, timeout=timeout_ms)


SCREENS = {"unused": "not in use", "pair": "Connect this tablet", "pairs": "pairs of handovers",
           "back": "moving back", "hint": "do anything differently", "place": "Handover",
           "wait": "Please wait", "rate": "Compared with", "done": "Thank you", "go": "Go!",
           **{q.id: q.text[:30] for q in QUESTIONS}}


def shown_screen(page: Page, not_: str | tuple[str, ...] = (), unused_ok: bool = False
                 ) -> str | None:
    """The known screen the tablet shows now if it is not one of ``not_`` (one name or several),
    else None. "Not in use" counts only with ``unused_ok`` (a reloaded page is briefly the second
    page, until the server has seen the old one close)."""
    skip = {not_} if isinstance(not_, str) else set(not_)
    if not unused_ok:
        skip.update(("unused", "pair"))
    text = page.inner_text("body")
    return next((name for name, marker in SCREENS.items() if marker in text and name not in skip),
                None)


def tablet_screen(page: Page, not_: str | tuple[str, ...] = (), timeout_s: float = 90.0,
                  unused_ok: bool = False) -> str:
    """Wait until the tablet shows a known screen other than ``not_`` (:func:`shown_screen`);
    return its name."""
    return wait_for(lambda: shown_screen(page, not_, unused_ok),
                    f"the tablet to show a screen other than {not_!r}",
                    timeout=timeout_s, seen=lambda: what_it_showed(page), poll=PAGE_POLL_S)


#: A trial's end as the dashboard's Recent events say it (app/session/supervisor.py): "trial 1
#: aborted: tracker_lost: no valid hand sample for 0.104 s (staleness_limit_s = 0.1)".
TRIAL_ENDED = r"\btrial {index} (completed|not_taken|aborted)(?:: ([^\n]*))?"


def trial_ended(dashboard: Page, index: int) -> tuple[str, str | None] | None:
    """Trial ``index``'s outcome and reason once the dashboard says it ended; None before."""
    found = re.search(TRIAL_ENDED.format(index=index), dashboard.inner_text("body"))
    return None if found is None else (found.group(1), found.group(2))


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
    # A product rule, not a wait for a state: the tablet ignores input for SETTLE_S after a screen
    # change (app/ui/deliberate.py) and keeps that window on the server; the page does not show
    # whether input is armed yet. The server starts the window when it sends the screen, before the
    # page can show it, and this sleep starts after the page showed it: on any load, input sent after
    # it arrives outside the window. (+0.1 s: the server's window starts a little after it queued the
    # screen, app/ui/tablet.py TabletClient._draw.)
    time.sleep(SETTLE_S + 0.1)


def double_tap(page: Page, name: str, gap_s: float = 0.15) -> None:
    """Two finger taps ``gap_s`` apart on the spot where button ``name`` is now (the second lands
    on whatever the first one brought up)."""
    point = tap_point(page, name)
    page.touchscreen.tap(*point)
    # A human double tap's gap, deliberate. Load only stretches it, and the tests' outcome holds for
    # any gap: the second tap lands on the same screen (ignored: busy, settling, or a stale answer
    # refused) or on the next screen's button, disabled or absent there; the store holds one answer.
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
        wait_enabled(tablet, "Confirm")
        shot(tablet, folder, "tablet-rate")
    return timed_tap(tablet, "Confirm", "rate")


def confirm_placement(tablet: Page) -> float:
    """Tap Confirm on the scale; seconds until the tablet shows the next screen (the engine has
    stored the placement before it publishes the next state)."""
    point = tap_point(tablet, "Confirm")
    began = time.perf_counter()
    tablet.touchscreen.tap(*point)
    wait_function(tablet, "() => !document.querySelector('.hl-scale')",
                  "the scale to go after Confirm")
    return time.perf_counter() - began  # reported (benchmarks/ui_latency.py), never asserted


def open_participant(dashboard: Page, code: str, scenario: str = "straightforward") -> None:
    """Unlock the dashboard if it is locked, then create or resume ``code``, with ``scenario``
    when the Scenario field has none yet (no study plan proposed one; a resumed session keeps its
    own; straightforward by default: its handovers take half as long as the perturbed one's).
    Waits until the page shows either state (the token prompt or the participant's Code field) and
    acts on what came: a page read once before it rendered would look unlocked."""
    if dashboard_state(dashboard) == "locked":
        unlock_dashboard(dashboard)
    fill(dashboard, "Code", code)
    if labelled(dashboard, "Scenario").input_value() == CHOOSE:
        choose(dashboard, "Scenario", scenario)
    click(dashboard, "Create or resume")
    wait_text(dashboard, "handovers completed")


def choose(page: Page, label: str, option: str) -> None:
    """Choose ``option`` in the dropdown labelled ``label`` (viser's Mantine Select: a click opens
    its options) and wait until the field shows it."""
    field = labelled(page, label)
    with awaiting(page, f"choosing {option!r} in {label!r}"):
        field.click()
        page.get_by_role("option", name=option, exact=True).click()
    wait_function(page, "([f, v]) => f.value === v", f"{label!r} to show {option!r}",
                  arg=[field.element_handle(), option])


def dashboard_state(dashboard: Page) -> str:
    """Wait until the dashboard shows the token prompt ("locked") or the Code field of "Create or
    resume" ("unlocked"), and say which."""
    code = labelled(dashboard, "Code")

    def state() -> str | None:
        if "Enter the dashboard token" in dashboard.inner_text("body"):
            return "locked"
        return "unlocked" if code.count() and code.first.is_visible() else None

    return wait_for(state, "the dashboard's token prompt or its participant Code field",
                    seen=lambda: what_it_showed(dashboard), poll=PAGE_POLL_S)


@dataclass
class Served:
    process: subprocess.Popen
    tablet_url: str
    dashboard_url: str
    study: Path
    log: Path

    def shutdown(self, timeout: float = CEILING_S) -> str:
        """Ctrl-C, as the experimenter would; returns the server's output. ``timeout`` is a ceiling
        for a hung shutdown (it stops the arm and closes the session), not a bound."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                raise AssertionError(f"handover serve did not end {timeout:g} s after Ctrl-C; its "
                                     f"output:\n{tail(self.log.read_text())}") from None
        return self.log.read_text()


#: The URLs serve prints once its servers are bound (app/ui/cli.py).
URL_LINES = {"tablet": re.compile(r"^tablet \(participant\):\s+(http://\S+)$", re.M),
             "dashboard": re.compile(r"^dashboard \(experimenter\):\s+(http://\S+)$", re.M)}
#: Its last line of start-up: the servers are bound and the dashboard's token is known.
STARTED = "dashboard token:"


@contextmanager
def serve(tmp: Path, *extra: str, rate: int = 125, protocol_toml: str = SHORT_TOML,
          tables: str = "", token: str | None = TOKEN, ports: tuple[int, int] | None = None,
          log_name: str = "serve.log", verbose: bool = True) -> Iterator[Served]:
    """`handover serve` on two loopback ports the server binds itself (port 0: any free one; or
    ``ports``: tablet, dashboard, e.g. those a first run of the same test bound) with a lab config
    of the short protocol (``protocol_toml`` is its [protocol] table; ``tables``: more tables of
    the lab config, e.g. :data:`NEVER_TAKES`) at ``rate`` Hz (125 for speed); ``token`` None: the
    study's own dashboard token; its output in ``tmp/log_name``
    (``verbose``, the default: at INFO level, every message the dashboard shows and every step of
    the session, so that a failure's log tail says what the server did while a page showed
    something else). The URLs are read from the server's output once it says it has started."""
    tmp.mkdir(parents=True, exist_ok=True)
    config = tmp / "lab.toml"
    config.write_text(f"[loop]\nrate_hz = {rate}\n\n[protocol]\n{protocol_toml}\n{tables}")
    study, log = tmp / "study", tmp / log_name
    tablet, dashboard = ports or (0, 0)
    command = [sys.executable, "-m", "app.cli", *(["--verbose"] if verbose else []), "serve",
               "--study", str(study),
               "--tablet-port", str(tablet), "--dashboard-port", str(dashboard),
               "--config", str(config), *(["--token", token] if token else []),
               # The rig process under SCHED_FIFO where permitted, by default, as a lab runs it: on
               # the normal policy a stalled rig on a loaded machine wrote no sample for 0.5 s, the
               # backstop killed it as it must, and a session test stood at "the arm has a fault"
               # (test_serve_kill under a load of 13 in a full make test).
               *extra]
    with log.open("w") as out:
        process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                   env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        urls = wait_for(lambda: started(process, log), "handover serve to print its URLs and token",
                        seen=lambda: tail(log.read_text()))
        served = Served(process, urls["tablet"], urls["dashboard"], study, log)
        _LOGS.update({served.tablet_url: log, served.dashboard_url: log})
        yield served
    finally:
        for url in [url for url, path in _LOGS.items() if path == log]:
            del _LOGS[url]
        if process.poll() is None:
            process.kill()
            process.wait()


def started(process: subprocess.Popen, log: Path) -> dict[str, str] | None:
    """The URLs serve printed ({"tablet": …, "dashboard": …}) once it has started; None before.
    Raises at once if serve has exited (a dead server is not a slow one)."""
    text = log.read_text()
    if STARTED in text:
        urls = {role: pattern.search(text) for role, pattern in URL_LINES.items()}
        assert all(urls.values()), f"serve started without printing both URLs:\n{tail(text)}"
        return {role: match.group(1) for role, match in urls.items()}
    if (code := process.poll()) is not None:
        raise AssertionError(f"handover serve exited with {code} before it started; its output:\n"
                             f"{tail(log.read_text())}")
    return None


def ports_of(served: Served) -> tuple[int, int]:
    """The (tablet, dashboard) ports a server bound, to start the next one on the same ports."""
    return (int(served.tablet_url.rsplit(":", 1)[1]), int(served.dashboard_url.rsplit(":", 1)[1]))


@contextmanager
def chromium() -> Iterator[Browser]:
    """A Chromium of its own for the block, with its Playwright driver, closed when it ends.

    Launched for each block, not kept for a test process's later tests: a kept one (2026-11-30)
    saved ~2.5 CPU-s a launch here, and in its first CI run a screenshot of a page in it waited
    60 s for Chromium and failed, a stall not seen in the runs before with a browser a block
    (docs/testing.md, "One Chromium a test process")."""
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=chromium_args())
        try:
            yield browser
        finally:
            browser.close()


#: The dashboard (a laptop page) as the suite opens it. Viser's "Software WebGL rendering
#: detected" notice of headless Chromium is hidden (screenshots). So is the 3-D view, unless
#: screenshots are published (HANDOVER_DOC_FIGURES=1): no test reads the scene's pixels (the replay
#: and live-view tests check what the server sends), and here the scene is drawn by SwiftShader on
#: the CPU. Viser renders on demand, but every live-view update (10 Hz, app/ui/server.py TICK_S)
#: opens a 250 ms window of continuous frames, so during a trial the scene took all the CPU it could
#: get: 25–30 CPU-seconds of a 40 s dashboard test, out of 40 for all of Chromium (8 with the view
#: hidden). Hidden, the view's container is moved out of the viewport and viser's IntersectionObserver
#: stops its rendering (App.tsx ``DisableRender``); the scene's nodes are still created from every
#: message. Moved, not ``display: none``: at size 0 a remounted canvas (a reconnect) never starts its
#: frame loop, which also drains viser's messages, and the page stays without its GUI.
LAPTOP_CSS = (".mantine-Notification-root{display:none!important}"
              + ("" if os.environ.get("HANDOVER_DOC_FIGURES") == "1"
                 else " div:has(> div > div > canvas[data-engine]){transform:translateX(-300vw)!important}"))


def open_page(browser: Browser, url: str, touch: bool = False,
              size: tuple[int, int] = (1024, 768)) -> Page:
    context = browser.new_context(viewport={"width": size[0], "height": size[1]},
                                  has_touch=touch, is_mobile=False)
    if not touch:  # the tablet hides viser's notices itself (app/ui/style.py, KIOSK_CSS)
        context.add_init_script("document.addEventListener('DOMContentLoaded', () => {"
                                "const s = document.createElement('style');"
                                f"s.textContent = '{LAPTOP_CSS}';"
                                "document.head.appendChild(s); });")
    context.add_init_script(GUI_INPUT_JS)
    page = context.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    notices = _NOTICES.setdefault(page, [])
    page.on("pageerror", lambda exc: notices.append(f"uncaught {exc.name}: {exc.message} "
                                                    f"(stack: {(exc.stack or '')[:600]})"))
    page.on("console", lambda message: notable(message) and notices.append(
        f"console {message.type}: {message.text[:600]}"))
    with awaiting(page, f"opening {url}"):
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
    return wait_for(lambda: re.search(r"pairing code (\d{4})", dashboard.inner_text("body")),
                    "the dashboard's pairing code", seen=lambda: what_it_showed(dashboard),
                    poll=PAGE_POLL_S).group(1)


def pair_tablet(dashboard: Page, tablet: Page) -> None:
    """Type the dashboard's pairing code on the tablet with the on-screen keyboard and tap Connect;
    wait until the tablet shows the study's screen."""
    wait_text(tablet, "Connect this tablet")
    settle()
    fill(tablet, "Code", pairing_code(dashboard))
    tap(tablet, "Connect")
    tablet_screen(tablet)


def wait_ready(page: Page) -> None:
    """Wait until viser has connected and drawn something."""
    wait_function(page, "() => document.body && document.body.innerText.length > 0 && "
                        "!document.body.innerText.includes('Connecting')",
                  "the page to connect and draw", polling="raf")


def reload(page: Page) -> None:
    with awaiting(page, "reloading the page"):
        page.reload()
    wait_ready(page)


def wait_text(page: Page, text: str) -> None:
    """Wait until ``text`` is visible on the page."""
    with awaiting(page, f"waiting for the text {text!r}"):
        page.get_by_text(text, exact=False).first.wait_for(state="visible")


def wait_gone(page: Page, text: str) -> None:
    """Wait until the page's text no longer contains ``text``."""
    wait_function(page, "t => !document.body.innerText.includes(t)", f"{text!r} to go", arg=text)


def button(page: Page, name: str):
    return page.get_by_role("button", name=re.compile(f"^{re.escape(name)}$"))


def wait_enabled(page: Page, name: str) -> None:
    """Wait until a button ``name`` is shown and enabled (within its ceiling, :data:`CEILINGS_MS`)."""
    wait_function(page, "n => [...document.querySelectorAll('button')].some("
                        "b => !b.disabled && b.innerText.trim() === n)",
                  f"the button {name!r} enabled", arg=name,
                  timeout_ms=CEILINGS_MS.get(name, TIMEOUT_MS))


def click(page: Page, name: str) -> None:
    """Click button ``name`` once it is visible and enabled (within its ceiling, :data:`CEILINGS_MS`)."""
    with awaiting(page, f"clicking {name!r} (waits until it is visible and enabled)"):
        button(page, name).click(timeout=CEILINGS_MS.get(name, TIMEOUT_MS))


def tap_point(page: Page, name: str, enabled: bool = True) -> tuple[float, float]:
    """The centre of button ``name`` once it is visible (and enabled, unless ``enabled`` is
    False: to tap a disabled button)."""
    target = button(page, name)
    with awaiting(page, f"waiting for the button {name!r}" + (" enabled" if enabled else "")):
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
    return time.perf_counter() - began  # reported, never asserted


def labelled(page: Page, label: str):
    """The input labelled ``label`` (viser's labels are not <label> elements)."""
    return page.locator(f"xpath=//*[normalize-space(text())='{label}']/following::input[1]")


def fill(page: Page, label: str, value: str) -> None:
    """Type into the text field labelled ``label``."""
    with awaiting(page, f"typing into the field {label!r}"):
        labelled(page, label).fill(value)


def tick(page: Page, label: str, confirmed: str) -> None:
    """Tick the checkbox labelled ``label`` with one click, then wait until the server has taken
    it: the page shows ``confirmed`` (the server's own words for the new state) and the box is
    ticked. The server is the box's truth: a click is sent once, and the box shows what the server
    holds (a dashboard refresh once overwrote a click in flight: app/ui/dashboard.py Controls)."""
    box = labelled(page, label)
    with awaiting(page, f"clicking the checkbox {label!r}"):
        if not box.is_checked():
            box.click()
    wait_text(page, confirmed)
    wait_function(page, "b => b.checked", f"the checkbox {label!r} ticked",
                  arg=box.element_handle())


#: Whether a folder of viser's panel (by its title) is open and done opening: its content has a
#: height and no animation runs in it (Mantine's Collapse grows it over 200 ms, clipped, while the
#: panel may scroll to keep what is below it in place).
FOLDER_OPEN_JS = """(title) => {
  const label = [...document.querySelectorAll('div')].find(e => e.firstChild
    && e.firstChild.nodeType === Node.TEXT_NODE && e.firstChild.textContent === title);
  const content = label && label.nextElementSibling;
  return !!content && content.offsetHeight > 0
    && label.parentElement.getAnimations({subtree: true}).length === 0;
}"""


def open_folder(page: Page, title: str) -> None:
    """Open the panel's folder ``title`` and wait until it is done opening. A click while its
    content still grows can press a button that moves before it is released: Playwright checks
    only where the press lands, and the browser then sends no click to the button."""
    with awaiting(page, f"opening the folder {title!r}"):
        page.get_by_text(title, exact=True).first.click()
    wait_function(page, FOLDER_OPEN_JS, f"the folder {title!r} open", arg=title)


def unlock_dashboard(page: Page, token: str = TOKEN) -> None:
    """Type the token and press Unlock; wait for the unlocked dashboard (its STOP ARM)."""
    fill(page, "Token", token)
    click(page, "Unlock")
    wait_unlocked(page)


def wait_unlocked(page: Page) -> None:
    """Wait for the unlocked dashboard (its STOP ARM); a browser unlocked before needs no token."""
    with awaiting(page, "waiting for the unlocked dashboard (STOP ARM)"):
        button(page, "STOP ARM").wait_for(state="visible")


def touch_drag_to(page: Page, fraction: float, steps: int = 12, settled: bool = True) -> None:
    """Drag the scale's handle (the slider thumb) with one finger to ``fraction`` of the track,
    once the screen has settled (``settled`` False: at once)."""
    if settled:
        settle()
    with awaiting(page, "waiting for the scale's slider"):
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
        time.sleep(0.01)  # a finger's pace between moves; where the handle ends is the last move's
    # While the finger is down, no number is shown: no value label, no number box, no end marks.
    shown = page.evaluate("() => { const f = document.querySelector('.mantine-Slider-root')"
                          ".closest('.mantine-Flex-root'); const box = f.querySelector("
                          "'.mantine-NumberInput-root'); return [f.innerText, box ? "
                          "box.offsetParent !== null : false]; }")
    assert not re.search(r"\d", shown[0]) and not shown[1], f"a number shows while dragging: {shown}"
    touch("touchEnd", x1)
    cdp.detach()
    # The server redraws the newest marker where it received the handle: wait until it has.
    wait_function(
        page, "() => { const m = document.querySelector('.hl-new'); const t = document.querySelector("
        "'.mantine-Slider-thumb'); return m && t && Math.abs(parseFloat(m.style.left) - "
        "100 * parseFloat(t.getAttribute('aria-valuenow'))) < 0.05 || "
        "document.body.innerText.includes('Same as'); }",
        f"the server to redraw the newest marker at the dropped handle ({fraction:g})")


def in_viewport(page: Page, name: str) -> bool:
    """Whether button ``name`` lies wholly inside the window and is the element at its centre
    (nothing covers it)."""
    return page.evaluate(
        """name => { const b = [...document.querySelectorAll('button')].find(
               e => e.innerText.trim() === name);
           if (!b) return false;
           const r = b.getBoundingClientRect();
           const inside = r.top >= 0 && r.left >= 0 && r.bottom <= innerHeight &&
                          r.right <= innerWidth && r.height > 0;
           const hit = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
           return inside && b.contains(hit); }""", name)


def wait_still(page: Page) -> None:
    """Wait until no animation or transition runs on the page (a panel done collapsing, a folder
    done opening), two frames in a row."""
    wait_function(page, """() => { const still = document.getAnimations().every(
        a => a.playState !== 'running'); const was = window.__hlStill; window.__hlStill = still;
        return still && was; }""", "the page to stop animating", polling="raf")


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
    pressed = False

    def step() -> T | None:
        nonlocal pressed
        if (result := done()) is not None:
            return result
        ready = READY_TO_START in dashboard.inner_text("body")
        if ready and not pressed:
            click(dashboard, "Start trial")
        pressed = ready
        return None

    # The ceiling of a whole session's worth of trials (34 on the paper's protocol), not a bound.
    return wait_for(step, "the session to reach the awaited point while Start trial is pressed "
                          "each time the dashboard is ready", timeout=timeout_s,
                    seen=lambda: what_it_showed(dashboard), poll=PAGE_POLL_S)
