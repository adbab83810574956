"""The page each screen's browser loads: viser's client, from a copy of its build folder whose
``index.html`` is the study's own.

viser serves its client (one ``index.html``; a later build may add files beside it) from a folder
on the same port as its websocket. ``handover serve`` gives each server a copy of that folder in
which ``index.html`` carries, from its first byte, before viser's own script runs:

* **the study's title** (:attr:`ClientPage.title`): the tablet's tab says "Handover study" (nothing
  that tells θ or the condition), the dashboard's "handover-lab dashboard"; viser's says "Viser";
* **the screen's CSS** (:attr:`ClientPage.css`): the tablet's kiosk and both screens' offline cover
  (:func:`app.ui.style.offline_cover`), so a page reloaded while the server is down, or still
  connecting, shows the project's cover and never viser's own screens (its settings, its editable
  ``ws://`` address, "Dev Settings");
* **a small script** (:data:`PAGE_SCRIPT`; a served page's scripts run, those of ``add_html`` do not):

  - *the browser's id*: a random id kept in the page's ``localStorage`` and sent as the cookie
    ``hl-<role>-browser`` with the websocket handshake (``SameSite=Strict``), which
    :meth:`app.ui.guard.Guard.browser_of` reads: the paired tablet and an unlocked dashboard are
    recognised per browser across reconnects and restarts of the same study on the same ports
    (``localStorage`` belongs to the page's host and port);
  - *typed text first*: viser's client sends a text field's value through a sender throttled at
    50 ms whose held value is lost when another input (a button's click) follows within the
    window: a token pasted and Unlock clicked at once reached the server as the old value, and a
    typed token as its first letters. A click that follows typing in a text field is held until
    :data:`HOLD_MS` after the last keystroke, then repeated;
  - *Enter*: in a field of :attr:`ClientPage.enter` it presses that field's button (the token's
    Unlock, the pairing code's Connect), after the same hold;
  - *the watchdog*: viser retries a lost connection only while its page has the focus; a page
    whose screen (``.hl-live``) viser shows as disconnected for :data:`RECONNECT_AFTER_MS`, or
    that has no screen of the server's for :data:`FIRST_CONNECT_MS` (loading, or connected and
    waiting for its screen), asks the server for the page every second and reloads once it
    answers, focused or not. (A reload sooner than that cut into a page still receiving its
    screen on a loaded machine, and the next load was slower still.)

How the copy is served: viser 1.1.1 has no option for the folder; :class:`StudyViserServer` sets
the infra server's ``_http_server_root`` as ``ViserServer.__init__`` assigns it, before that
server's thread starts (the only moment it is read). Nothing of viser is patched. If a later viser
has no ``index.html`` with a ``<title>`` and a ``</head>``, or other names, the page is viser's own
and a warning says so: the screens still work (their CSS comes with every screen too), without the
title, the cover on reload, the browser's id, the held click and the watchdog.
"""

from __future__ import annotations

import html
import json
import logging
import shutil
import tempfile
from pathlib import Path

import viser
from pydantic import BaseModel, ConfigDict

from app.ui.style import DISCONNECTED, STOP_LABEL

log = logging.getLogger(__name__)

#: viser's own client build.
VISER_BUILD = Path(viser.__file__).resolve().parent / "client" / "build"
#: A click this soon after the last keystroke in a text field waits until then [ms]: longer than
#: the 50 ms of viser's throttled sender and a slow frame, short enough not to be noticed.
HOLD_MS = 200
#: A screen shown as disconnected this long, and the watchdog asks for the page [ms].
RECONNECT_AFTER_MS = 3000
#: No screen of the server's this long (loading, or waiting for the screen on a busy machine) [ms].
FIRST_CONNECT_MS = 15000
#: The browser id's form (hex digits of 16 random bytes).
BROWSER_ID_PATTERN = r"[0-9a-f]{32}"

#: The page's script; ``__ROLE__`` and ``__ENTER__`` are filled in per screen (JSON).
PAGE_SCRIPT = """(() => {
  const role = __ROLE__, enter = __ENTER__;
  try {
    let id = localStorage.getItem('hl-browser');
    if (!/^__PATTERN__$/.test(id || '')) {
      id = Array.from(crypto.getRandomValues(new Uint8Array(16)),
                      (b) => b.toString(16).padStart(2, '0')).join('');
      localStorage.setItem('hl-browser', id);
    }
    document.cookie = `hl-${role}-browser=${id}; path=/; SameSite=Strict; max-age=31536000`;
  } catch (error) { console.warn('handover: no browser id', error); }

  let typed = -1e9;
  const wait = () => Math.max(0, typed + __HOLD__ - performance.now());
  addEventListener('input', (event) => {
    if (event.target instanceof HTMLInputElement && event.target.type === 'text') {
      typed = performance.now();
    }
  }, true);
  addEventListener('click', (event) => {
    const button = event.target instanceof Element && event.target.closest('button');
    if (!button || !event.isTrusted || wait() === 0 || button.innerText.trim() === __STOP__) return;
    event.stopImmediatePropagation();
    event.preventDefault();
    setTimeout(() => button.click(), wait());
  }, true);
  const fieldOf = (label) => document.evaluate(
    `//*[normalize-space(text())='${label}']/following::input[1]`, document, null,
    XPathResult.FIRST_ORDERED_NODE_TYPE, null).singleNodeValue;
  addEventListener('keydown', (event) => {
    if (event.key !== 'Enter') return;
    const label = Object.keys(enter).find((l) => fieldOf(l) === event.target);
    const button = label && [...document.querySelectorAll('button')].find(
      (b) => b.innerText.trim() === enter[label] && !b.disabled);
    if (!button) return;
    event.preventDefault();
    setTimeout(() => button.click(), wait());
  }, true);

  const grace = () => !document.querySelector('.hl-live') ? __FIRST__
    : document.querySelector(__DISCONNECTED__) ? __RECONNECT__ : null;
  let since = null, asking = false;
  setInterval(async () => {
    const wait = grace();
    if (wait === null) { since = null; return; }
    since = since ?? performance.now();
    if (asking || performance.now() - since < wait) return;
    asking = true;
    try {
      if ((await fetch(location.href, {cache: 'no-store'})).ok) location.reload();
    } catch (error) { /* the server is still down: ask again in a second */ }
    asking = false;
  }, 1000);
})();"""


class ClientPage(BaseModel):
    """What one screen's page carries besides viser's client."""

    model_config = ConfigDict(frozen=True)

    role: str  # "tablet", "dashboard": names the browser-id cookie
    title: str  # the tab's title
    css: str  # applied from the page's first byte
    enter: dict[str, str] = {}  # text field label → the button Enter presses

    def script(self) -> str:
        fill = {"__ROLE__": json.dumps(self.role), "__ENTER__": json.dumps(self.enter),
                "__PATTERN__": BROWSER_ID_PATTERN, "__HOLD__": str(HOLD_MS),
                "__STOP__": json.dumps(STOP_LABEL),
                "__DISCONNECTED__": json.dumps(DISCONNECTED),
                "__RECONNECT__": str(RECONNECT_AFTER_MS), "__FIRST__": str(FIRST_CONNECT_MS)}
        script = PAGE_SCRIPT
        for placeholder, value in fill.items():
            script = script.replace(placeholder, value)
        return script

    def head(self) -> str:
        """What goes into ``<head>`` before viser's own script."""
        return (f"<title>{html.escape(self.title)}</title><style>{self.css}</style>"
                f"<script>{self.script()}</script>")


def client_folder(page: ClientPage, build: Path = VISER_BUILD) -> Path | None:
    """A fresh copy of viser's ``build`` folder whose ``index.html`` carries ``page`` (the caller
    removes it); None, with a warning, if ``build`` is not what this was written against."""
    index = build / "index.html"
    text = index.read_text(encoding="utf-8") if index.is_file() else ""
    title_start, title_end = text.find("<title>"), text.find("</title>")
    if not 0 <= title_start < title_end < text.find("</head>"):
        log.warning("viser's client at %s has no index.html with a <title> in its <head>: the "
                    "screens use viser's own page (no study title, no cover on a reload, no "
                    "watchdog, no browser id)", build)
        return None
    folder = Path(tempfile.mkdtemp(prefix=f"handover-{page.role}-page-"))
    shutil.copytree(build, folder, dirs_exist_ok=True)
    (folder / "index.html").write_text(
        text[:title_start] + page.head() + text[title_end + len("</title>"):], encoding="utf-8")
    return folder


class StudyViserServer(viser.ViserServer):
    """A viser server whose client page comes from ``client_root`` (:func:`client_folder`;
    None: viser's own), removed again by :meth:`stop`."""

    def __init__(self, *args, client_root: Path | None = None, **kwargs) -> None:
        self._client_root = client_root
        try:
            super().__init__(*args, **kwargs)
        except BaseException:
            self._remove_client_root()
            raise
        served = getattr(getattr(self, "_websock_server", None), "_http_server_root", None)
        if client_root is not None and served != client_root:
            log.warning("this viser (%s) did not take the study's page folder: the screens use "
                        "viser's own page", viser.__version__)

    def __setattr__(self, name: str, value: object) -> None:
        # ViserServer.__init__ assigns its infra server before it starts it; its thread reads the
        # folder when it starts
        if (name == "_websock_server" and self.__dict__.get("_client_root") is not None
                and hasattr(value, "_http_server_root")):
            value._http_server_root = self._client_root
        super().__setattr__(name, value)

    def stop(self) -> None:
        super().stop()
        self._remove_client_root()

    def _remove_client_root(self) -> None:
        if self._client_root is not None:
            shutil.rmtree(self._client_root, ignore_errors=True)
