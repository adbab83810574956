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

import pytest
from support.between import Between
from support.browser import chromium, open_page, sending, wait_text, watch_client
from support.waiting import wait_for

from app.ui.guard import open_server

pytestmark = [pytest.mark.browser]


def test_a_page_gets_a_message_pushed_between_the_producers_look_and_its_wait() -> None:
    # held just after asyncio.Event.wait's look at the flag, before its registration as a waiter
    between = Between(asyncio.Event.wait, "create_future")
    with between.tracing():
        server, _ = open_server("127.0.0.1", 0, "dashboard")  # the product's server, as serve opens it
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
            between.arm(lambda frame: frame.f_locals.get("self") is buffer.message_event)
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
