"""A page keeps getting its messages when a handle is set from another thread at the worst moment.

viser's producer for a page (a task on the server's event loop) looks at its buffer's event flag,
then registers as a waiter; a ``set()`` from another thread that comes between the two sets the
flag without waking it, and the page gets nothing more (:mod:`app.ui.streams`). Here the race is
made to happen, not hoped for: a trace function on the event loop's thread holds that producer
exactly between its look and its registration while the test, from its own thread, sets the text of
a markdown on the page; then the producer goes on. The page (headless Chromium) must show the new
text, and the server must have handed it over. Without :func:`app.ui.streams.safe_streams` the
producer sleeps on a set flag for good and neither happens.
"""

from __future__ import annotations

import asyncio
import inspect
import threading
from collections.abc import Callable
from types import FrameType

import pytest
from support.browser import chromium, open_page, sending, wait_text, watch_client
from support.waiting import CEILING_S, wait_for

from app.ui.guard import open_server

pytestmark = [pytest.mark.browser]

#: The line of ``asyncio.Event.wait`` just after its look at the flag, before its registration.
WAIT = asyncio.Event.wait.__code__
_lines, _first = inspect.getsourcelines(asyncio.Event.wait)
AFTER_LOOK = _first + next(i for i, line in enumerate(_lines) if "create_future" in line)


class Between:
    """Holds the event loop's thread once, when a producer waits on ``event()`` and has looked at
    its flag but not yet registered, until :meth:`release`. Installed with ``threading.settrace``
    before the server's thread starts (a trace function is per thread)."""

    def __init__(self) -> None:
        self.event: Callable[[], object] | None = None
        self.holding, self.released = threading.Event(), threading.Event()

    def arm(self, event: Callable[[], object]) -> None:
        self.event = event

    def trace(self, frame: FrameType, kind: str, arg: object):
        if kind == "call" and frame.f_code is WAIT and self.event is not None:
            return self._line
        return None

    def _line(self, frame: FrameType, kind: str, arg: object):
        if (kind == "line" and frame.f_lineno == AFTER_LOOK and self.event is not None
                and frame.f_locals.get("self") is self.event()):
            self.event = None  # once
            self.holding.set()
            self.released.wait(CEILING_S)  # a ceiling for a test that failed before releasing
        return self._line

    def release(self) -> None:
        self.released.set()


def test_a_page_gets_a_message_pushed_between_the_producers_look_and_its_wait() -> None:
    between = Between()
    threading.settrace(between.trace)
    try:
        server, _ = open_server("127.0.0.1", 0, "dashboard")  # the product's server, as serve opens it
    finally:
        threading.settrace(None)
    connected: list = []
    server.on_client_connect(connected.append)
    try:
        with chromium() as browser:
            page = open_page(browser, f"http://127.0.0.1:{server.get_port()}")
            [client] = wait_for(lambda: connected, "the page connected", seen=lambda: connected)
            watch_client(page, client)
            text = client.gui.add_markdown("before the race")
            wait_text(page, "before the race")
            buffer = client._websock_connection.get_message_buffer()
            between.arm(lambda: buffer.message_event)
            text.content = "the producer goes round"  # it sends this, then waits again: held there
            wait_for(between.holding.is_set, "the producer held between its look and its wait",
                     seen=lambda: sending(client))
            text.content = "pushed in between"  # from this thread, while the loop's thread is held
            between.release()
            wait_text(page, "pushed in between")
            wait_for(lambda: "0 messages not yet sent" in sending(client),
                     "the server to have handed every message over", seen=lambda: sending(client))
    finally:
        between.release()
        server.stop()
