"""The dashboard windows open on one session, and which one controls it.

Two unlocked dashboard windows could each press Start, and neither said the other was open. Now
every unlocked window is known with its remote address, each window is told how many are open and
from where, and one window controls the session: the first unlocked while none controls. The
others are view-only until the experimenter takes control on one of them (which makes the
controlling one view-only). When the controlling window closes (or reloads), the one window left
controls; with more left, none controls until one takes control or a window is unlocked. (A window
that reloads may be unlocked again before the server has seen its old page close: it controls as
soon as the old page is gone.) **STOP ARM is no control**: it works from every window,
always (the dashboard never asks this module about it).
"""

from __future__ import annotations

import logging
import threading

from pydantic import BaseModel, ConfigDict

from app.protocol.errors import RefusedAction

log = logging.getLogger(__name__)


class WindowStatus(BaseModel):
    """What one window shows about the windows open."""

    model_config = ConfigDict(frozen=True)

    addresses: list[str]  # the remote address of every unlocked window, in the order they opened
    controlling: bool  # this window controls the session
    controller: str | None  # the controlling window's address (None: no window controls)

    def words(self) -> str:
        """Markdown for the window: nothing while it is the only one; otherwise how many are open,
        from where, and whether this one controls."""
        if len(self.addresses) < 2 and self.controlling:
            return ""
        where = ", ".join(self.addresses)
        count = len(self.addresses)
        open_ = "1 dashboard window is open" if count == 1 else f"{count} dashboard windows are open"
        head = f"⚠ **{open_}** ({where})."
        if self.controlling:
            return f"{head} **This window controls the session**; the others are view-only."
        who = (f"the window at {self.controller} controls the session" if self.controller
               else "no window controls the session")
        return (f"{head} **This window is view-only**: {who}. Press **Take control** to control "
                "it from here. STOP ARM works from every window.")


class DashboardWindows:
    """The unlocked dashboard windows by their viser client id, and the controlling one."""

    def __init__(self) -> None:
        self._addresses: dict[int, str] = {}
        self._controller: int | None = None
        self._lock = threading.Lock()

    def opened(self, window: int, address: str) -> None:
        """A window was unlocked from ``address``; it controls if no window does."""
        with self._lock:
            self._addresses[window] = address
            if self._controller is None:
                self._controller = window
            log.info("dashboard window %d unlocked from %s (%d open)", window, address,
                     len(self._addresses))

    def closed(self, window: int) -> None:
        with self._lock:
            self._addresses.pop(window, None)
            if self._controller == window:
                self._controller = next(iter(self._addresses)) if len(self._addresses) == 1 \
                    else None

    def take(self, window: int) -> None:
        """The experimenter takes control on ``window`` (an unlocked one)."""
        with self._lock:
            if window not in self._addresses:
                raise RefusedAction("take control refused: this window is not unlocked")
            self._controller = window
            log.info("dashboard control taken by window %d at %s", window, self._addresses[window])

    def require_control(self, window: int) -> None:
        """Refuse a control's action from a view-only window."""
        if self._controller != window:
            raise RefusedAction("this dashboard window is view-only (another window controls the "
                                "session): press Take control first")

    def status(self, window: int) -> WindowStatus:
        with self._lock:
            controller = self._controller
            return WindowStatus(addresses=list(self._addresses.values()),
                                controlling=controller == window,
                                controller=None if controller is None else
                                self._addresses.get(controller))
