"""One tablet per session: which page on the tablet port is the participant's tablet.

The dashboard shows a short pairing code; a page on the tablet port becomes the study's tablet when
the code is typed on it. The pairing belongs to the device's address, so the paired tablet stays
paired across a reload (a new page from the same address); a page from any other address must type
the code, which moves the session to it (a tablet swapped mid-study). Of several open pages of the
paired address, the one that connected first is the tablet; every other page is offered nothing to
rate. Wrong codes are rate-limited per address (:class:`~app.session.access.AttemptLimit`).
"""

from __future__ import annotations

import logging
import secrets
import threading
from collections.abc import Callable
from typing import Literal

from pydantic import BaseModel, ConfigDict

from app.session.access import AttemptLimit

log = logging.getLogger(__name__)

#: Digits of the pairing code.
CODE_DIGITS = 4


class TabletStatus(BaseModel):
    """What the dashboard shows about the tablet port, and whether Start may go ahead."""

    model_config = ConfigDict(frozen=True)

    code: str
    pages: int = 0  # pages open on the tablet port
    paired: bool = False  # one of them is the paired tablet
    address: str | None = None  # the paired device's address

    @property
    def ready(self) -> bool:
        """Exactly one page is open and it is the paired tablet."""
        return self.paired and self.pages == 1

    def blocker(self) -> str | None:
        """Why a trial may not start as far as the tablet is concerned, in the experimenter's words
        (None: it may)."""
        if self.pages == 0:
            return f"no tablet is connected: open the tablet page and type the code {self.code}"
        if not self.paired:
            return f"the tablet is not paired: type the code {self.code} on it"
        if self.pages > 1:
            return (f"{self.pages} pages are open on the tablet port: close all but the "
                    "participant's tablet")
        return None


class TabletPairing:
    """The pages open on the tablet port and the paired address (thread-safe)."""

    def __init__(self, code: str | None = None, clock: Callable[[], float] | None = None) -> None:
        self.code = code or f"{secrets.randbelow(10 ** CODE_DIGITS):0{CODE_DIGITS}d}"
        self._pages: dict[int, str] = {}  # page → address, in the order they connected
        self._address: str | None = None
        self._lock = threading.Lock()
        self._limit = AttemptLimit(**({} if clock is None else {"clock": clock}))

    def connected(self, page: int, address: str) -> None:
        with self._lock:
            self._pages[page] = address

    def closed(self, page: int) -> None:
        with self._lock:
            self._pages.pop(page, None)

    def pair(self, page: int, code: str) -> str | None:
        """Pair ``page``'s device if ``code`` is right; None on success, otherwise why not."""
        with self._lock:
            address = self._pages.get(page)
            if address is None:
                return "This page is no longer connected."
            refusal = self._limit.check(address, code.strip(), self.code)
            if refusal is None:
                self._address = address
                # the page it was typed on is the tablet, ahead of older pages of that address
                self._pages = {page: address} | {p: a for p, a in self._pages.items() if p != page}
                log.info("tablet paired: page %d at %s", page, address)
            return refusal

    def role(self, page: int) -> Literal["tablet", "unused", "pair"]:
        """What ``page`` is: the study's tablet (the first open page of the paired address),
        another page of that device ("not in use"), or a page that may pair with the code."""
        with self._lock:
            tablet = next((p for p, a in self._pages.items() if a == self._address), None)
            if page == tablet:
                return "tablet"
            return "unused" if self._pages.get(page) == self._address else "pair"

    def status(self) -> TabletStatus:
        with self._lock:
            paired = any(a == self._address for a in self._pages.values())
            return TabletStatus(code=self.code, pages=len(self._pages), paired=paired,
                                address=self._address)
