"""viser's message streams to the pages, woken safely whatever thread sets a handle.

viser 1.1.1 sends each page its messages from a producer task on the server's event loop: one for
the page's own buffer, one for the server-wide buffer. With nothing queued, a producer waits on its
buffer's ``asyncio.Event``; every ``push`` (made by whichever thread assigned a handle's property:
the live view's ticker, a replay, the session runner's threads) calls that event's ``set()``
directly. ``asyncio.Event`` is not thread-safe: a ``set()`` from another thread that comes between
the producer's look at the flag and its registration as a waiter sets the flag without waking it,
and every later ``set()`` finds the flag set and wakes nothing. That page then gets nothing more
from the server, for good: its text stays as it was while its connection, its clicks and the
server's state go on. (The dashboard that stopped at a trial's Go while the session went on, the
replay that never said "finished".)

Here each buffer's event is replaced by a :class:`LoopSafeEvent`, whose ``set()`` from another
thread is handed to the event loop (``call_soon_threadsafe``), where it cannot come between the
producer's look and its wait. Nothing of viser is patched; like :mod:`app.ui.guard` this reaches
into its infra server (``ViserServer._websock_server``: its broadcast buffer and its
``on_client_connect`` hook, called before a page's producers start). Re-check when viser is
upgraded.
"""

from __future__ import annotations

import asyncio
import contextlib

import viser
from viser.infra import WebsockClientConnection


class LoopSafeEvent(asyncio.Event):
    """An ``asyncio.Event`` of one event loop that any thread may set: a ``set()`` from outside the
    loop runs on the loop, so it never interleaves with a waiter's look at the flag."""

    def __init__(self, loop: asyncio.AbstractEventLoop, value: bool = False) -> None:
        super().__init__()
        self._home = loop
        if value:
            super().set()

    def set(self) -> None:
        try:
            here = asyncio.get_running_loop()
        except RuntimeError:
            here = None
        if here is self._home:
            super().set()
            return
        with contextlib.suppress(RuntimeError):  # a closed loop: no producer waits any more
            self._home.call_soon_threadsafe(super().set)


def _wake_safely(buffer) -> None:
    """Replace the event a viser message buffer's producers wait on by a :class:`LoopSafeEvent`."""
    buffer.message_event = LoopSafeEvent(buffer.event_loop, buffer.message_event.is_set())


def safe_streams(server: viser.ViserServer) -> None:
    """Every message stream of ``server`` wakes safely: the server-wide one now, each page's own
    as the page connects (before its producer starts)."""
    infra = server._websock_server
    _wake_safely(infra.get_message_buffer())

    def connected(connection: WebsockClientConnection) -> None:
        _wake_safely(connection.get_message_buffer())

    infra.on_client_connect(connected)
