"""One tablet per session: which page on the tablet port is the participant's tablet.

The dashboard shows a short pairing code; a page on the tablet port becomes the study's tablet when
the code is typed on it. The pairing belongs to the browser it was typed in (the id its page keeps,
app/ui/client_page.py; a page without one: to its address), so the paired tablet stays paired across
a reload; a page of any other browser must type the code — another browser behind the same address
(a NAT, a second device on the lab's network) too — which moves the session to it (a tablet swapped
mid-study, or taken over: the dashboard's status line says so from then on). Of several open pages of
the paired browser, the one that connected first is the tablet; every other page is offered nothing
to rate. Wrong codes are
rate-limited per address (:class:`~app.session.access.AttemptLimit`), and after
:data:`CODE_GUESSES` wrong codes from all addresses together the code is replaced by a new one (the
dashboard shows it and says why): however many addresses guess, one code is guessed at most that
many times, one chance in a thousand for four digits.

A browser that paired is remembered in the study folder (:class:`~app.session.access.KnownBrowsers`,
by the id its page keeps): when it connects again, after a restart of ``handover serve`` or from a
new address, it is the tablet again without the code. Only the browser that paired last is
remembered: a tablet taken over is forgotten.

The dashboard's alert about wrong codes names the recent ones: those of the last
:data:`WRONG_CODE_ALERT_S`, and not those of an address that has paired since (a participant's typo
on the tablet that then paired is no alarm). The code's replacement still counts every wrong code.
"""

from __future__ import annotations

import logging
import secrets
import threading
import time
from collections.abc import Callable
from typing import Literal

from pydantic import BaseModel, ConfigDict

from app.session.access import AttemptLimit, KnownBrowsers

log = logging.getLogger(__name__)

#: Digits of the pairing code.
CODE_DIGITS = 4
#: Wrong codes, from all addresses together, after which the code is replaced.
CODE_GUESSES = 10
#: How long a wrong code stays in the dashboard's alert [s] (unless its address pairs first).
WRONG_CODE_ALERT_S = 600.0


def new_code() -> str:
    return f"{secrets.randbelow(10 ** CODE_DIGITS):0{CODE_DIGITS}d}"


class TabletStatus(BaseModel):
    """What the dashboard shows about the tablet port, and whether Start may go ahead."""

    model_config = ConfigDict(frozen=True)

    code: str
    pages: int = 0  # pages open on the tablet port
    paired: bool = False  # one of them is the paired tablet
    address: str | None = None  # the paired device's address (None: none paired yet)
    taken_over_from: str | None = None  # the address a later pairing moved the session from
    wrong_codes: int = 0  # recent wrong codes of addresses not paired since (WRONG_CODE_ALERT_S)
    guessers: int = 0  # the addresses they came from
    code_changes: int = 0  # codes replaced after CODE_GUESSES wrong ones

    def alert(self) -> str | None:
        """What the experimenter must notice, for the dashboard's status line: a take-over of the
        tablet, or wrong codes (None: neither)."""
        alerts = []
        if self.taken_over_from is not None:
            alerts.append(f"the tablet was taken over: paired from {self.taken_over_from}, now "
                          f"{self.address} (if that is not your tablet, Stop and re-pair)")
        if self.wrong_codes:
            alerts.append(f"{self.wrong_codes} wrong pairing code{'s' if self.wrong_codes > 1 else ''}"
                          f" from {self.guessers} address{'es' if self.guessers > 1 else ''}"
                          + (f"; the code was replaced {self.code_changes}×" if self.code_changes
                             else ""))
        return "; ".join(alerts) or None

    @property
    def ready(self) -> bool:
        """Exactly one page is open and it is the paired tablet."""
        return self.paired and self.pages == 1

    def blocker(self) -> str | None:
        """Why a trial may not start as far as the tablet is concerned, in the experimenter's words
        (None: it may)."""
        if self.pages == 0 and self.address is not None:
            return ("the paired tablet's page is closed: open the tablet page on it again (no code "
                    f"needed; another device types the code {self.code})")
        if self.pages == 0:
            return f"no tablet is connected: open the tablet page and type the code {self.code}"
        if not self.paired:
            return f"the tablet is not paired: type the code {self.code} on it"
        if self.pages > 1:
            return (f"{self.pages} pages are open on the tablet port: close all but the "
                    "participant's tablet")
        return None


class TabletPairing:
    """The pages open on the tablet port and the paired address (thread-safe); ``known``: the
    browser that paired, remembered across restarts (None: none is)."""

    def __init__(self, code: str | None = None, clock: Callable[[], float] | None = None,
                 known: KnownBrowsers | None = None) -> None:
        self.code = code or new_code()
        self._pages: dict[int, str] = {}  # page → address, in the order they connected
        self._browsers: dict[int, str | None] = {}  # page → its browser's id
        self._known = known
        self._address: str | None = None
        self._browser: str | None = None  # the paired browser's id (None: its page had none)
        self._taken_over_from: str | None = None
        self._guessed = 0  # wrong codes since the code was made
        self._code_changes = 0
        self._wrong: list[tuple[float, str]] = []  # (when, address) of each wrong code, for the alert
        self._lock = threading.Lock()
        self._clock = clock or time.monotonic
        self._limit = AttemptLimit(clock=self._clock)

    def connected(self, page: int, address: str, browser: str | None = None) -> bool:
        """A page opened; True if that paired it again: the browser that paired before, after a
        restart or from a new address (the same browser: not a take-over)."""
        with self._lock:
            self._pages[page], self._browsers[page] = address, browser
            if (self._known is None or (address, browser) == (self._address, self._browser)
                    or not self._known.known(browser)):
                return False
            self._address, self._browser = address, browser
            log.info("tablet paired again: page %d at %s is the browser paired before", page,
                     address)
            return True

    def closed(self, page: int) -> None:
        with self._lock:
            self._pages.pop(page, None)
            self._browsers.pop(page, None)

    def pair(self, page: int, code: str) -> str | None:
        """Pair ``page``'s device if ``code`` is right; None on success, otherwise why not."""
        with self._lock:
            address = self._pages.get(page)
            if address is None:
                return "This page is no longer connected."
            wrong_before = self._limit.wrong
            refusal = self._limit.check(address, code.strip(), self.code)
            if self._limit.wrong > wrong_before:
                self._guessed += 1
                self._wrong.append((self._clock(), address))
            if self._guessed >= CODE_GUESSES:
                self.code, self._guessed = new_code(), 0
                self._code_changes += 1
                log.warning("tablet: %d wrong pairing codes: the code was replaced (the dashboard "
                            "shows the new one)", CODE_GUESSES)
            if refusal is None:
                if self._address is not None and self._address != address:
                    self._taken_over_from = self._address
                    log.warning("tablet taken over: from %s to %s", self._address, address)
                self._address, self._browser = address, self._browsers.get(page)
                self._wrong = [(when, a) for when, a in self._wrong if a != address]
                if self._known is not None:
                    self._known.remember(self._browsers.get(page))
                # the page it was typed on is the tablet, ahead of older pages of that address
                self._pages = {page: address} | {p: a for p, a in self._pages.items() if p != page}
                log.info("tablet paired: page %d at %s", page, address)
            return refusal

    def _of_tablet(self, page: int) -> bool:
        """Whether ``page`` is of the paired browser (of its address, if it paired with no id)."""
        if self._address is None or page not in self._pages:
            return False
        if self._browser is not None:
            return self._browsers.get(page) == self._browser
        return self._pages[page] == self._address

    def role(self, page: int) -> Literal["tablet", "unused", "pair"]:
        """What ``page`` is: the study's tablet (the first open page of the paired browser),
        another page of that browser ("not in use"), or a page that may pair with the code."""
        with self._lock:
            tablet = next((p for p in self._pages if self._of_tablet(p)), None)
            if page == tablet:
                return "tablet"
            return "unused" if self._of_tablet(page) else "pair"

    def status(self) -> TabletStatus:
        with self._lock:
            paired = any(self._of_tablet(p) for p in self._pages)
            now = self._clock()
            self._wrong = [(when, a) for when, a in self._wrong if now - when < WRONG_CODE_ALERT_S]
            return TabletStatus(code=self.code, pages=len(self._pages), paired=paired,
                                address=self._address, taken_over_from=self._taken_over_from,
                                wrong_codes=len(self._wrong),
                                guessers=len({a for _, a in self._wrong}),
                                code_changes=self._code_changes)
