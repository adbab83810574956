"""Showing the session to the screens: the latest :class:`RunnerView`, its subscribers, and the
latest events (the dashboard's list).

A view is published two ways, and the difference is whether it waits for the engine thread:

- :meth:`Publisher.changed` makes a new view of the engine and the devices on the engine thread
  (waiting for it), numbered in the order views are made; a view made earlier than the one already
  shown is dropped (two threads publishing at once could otherwise show the older last: a dashboard
  stuck at "starting" with the trial's stage already stored, and Object loaded never enabled).
- :meth:`Publisher.news` publishes device news (Stop, the tablet, the hand's link) at once: the
  engine's part of the view shown, with the devices' status as it is now. It never waits for the
  engine thread, which may be busy with the learner for up to a minute.

Any thread but the engine thread publishes; the view shown and the subscribers are changed only
under the publishing lock, which the engine thread never takes (a subscriber may wait for the engine
thread: checked, ``forbid`` raises on it), and the events only under their own lock
(docs/architecture.md, "Threads and who owns what")."""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable

from app.session.engine_thread import SessionClosed
from app.session.view import RunnerView, Status, with_news

log = logging.getLogger(__name__)

#: How many recent events the dashboard lists.
MESSAGES = 5

Listener = Callable[[RunnerView], None]


class Publisher:
    """``make`` makes a numbered view on the engine thread (and waits for it); ``status`` reads the
    devices' status without it; ``forbid(what)`` raises when called on the engine thread."""

    def __init__(self, make: Callable[[], RunnerView], status: Callable[[], Status],
                 forbid: Callable[[str], None]) -> None:
        self._make, self._status, self._forbid = make, status, forbid
        self._publishing = threading.RLock()
        self._listeners: list[Listener] = []
        self._view = RunnerView()
        self._events_lock = threading.Lock()
        self._events: deque[str] = deque(maxlen=MESSAGES)
        self._closed = threading.Event()

    @property
    def view(self) -> RunnerView:
        """The latest published view (never blocks)."""
        return self._view

    def subscribe(self, listener: Listener) -> None:
        self._forbid("subscribing to the views (the publishing lock)")
        with self._publishing:
            self._listeners.append(listener)

    def messages(self) -> list[str]:
        """The latest events, newest last, each with its time of day."""
        with self._events_lock:
            return list(self._events)

    def close(self) -> None:
        """Publish nothing more (the session closes)."""
        self._closed.set()

    def changed(self, message: str | None = None) -> None:
        """A change, with its ``message`` for the log (None: none): a new view made on the engine
        thread."""
        self._forbid("publishing a change (the publishing lock)")
        self._log(message)
        if self._closed.is_set():
            return
        try:
            view = self._make()
        except SessionClosed:  # the session closed meanwhile: nothing more is shown
            return
        with self._publishing:
            if view.version > self._view.version:  # else a view made later is already shown
                self._notify(with_news(view, self._status()))

    def news(self, message: str | None = None) -> None:
        """Device news, with its ``message`` for the log: published at once over the engine's part
        of the view shown, without waiting for the engine thread."""
        self._forbid("publishing news (the publishing lock)")
        self._log(message)
        if not self._closed.is_set():
            with self._publishing:
                self._notify(with_news(self._view, self._status()))

    def _log(self, message: str | None) -> None:
        if message is not None:
            with self._events_lock:
                self._events.append(f"{time.strftime('%H:%M:%S')} {message}")
            log.info("%s", message)

    def _notify(self, view: RunnerView) -> None:
        """Show ``view`` (under the publishing lock)."""
        self._view = view
        for listener in list(self._listeners):
            try:
                listener(view)
            except Exception:
                log.exception("a screen failed to render")
