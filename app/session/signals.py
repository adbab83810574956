"""Waiting for the signal that ends ``handover serve``: SIGINT (Ctrl-C) or SIGTERM; and a close
that no such signal cuts short.

The kernel hands a process's signal to any of its threads that does not block it. Python runs the
handler in the main thread, but only once that thread runs again: a main thread asleep in
``Event.wait()`` slept on when the signal landed on another thread (seen: a SIGINT right after a
SIGCONT, one time in three, and serve never closed). The wakeup fd is written by the C-level
handler on whichever thread the signal lands, and wakes the main thread's ``select`` at once.
"""

from __future__ import annotations

import contextlib
import logging
import select
import signal
import socket
import threading
from collections.abc import Iterator
from types import TracebackType

log = logging.getLogger(__name__)

#: The signals that close serve as Ctrl-C does.
QUIT_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class QuitSignal:
    """Inside ``with``, SIGINT and SIGTERM are caught (none is lost from the moment it is entered);
    :meth:`wait` returns once one came. Must be entered on the main thread."""

    def __init__(self) -> None:
        self._received = threading.Event()
        self._reader, self._writer = socket.socketpair()
        self._writer.setblocking(False)
        self._before: dict[int, object] = {}
        self._wakeup_before = -1

    def __enter__(self) -> QuitSignal:
        self._wakeup_before = signal.set_wakeup_fd(self._writer.fileno(), warn_on_full_buffer=False)
        self._before = {signum: signal.signal(signum, self._receive) for signum in QUIT_SIGNALS}
        return self

    def _receive(self, _signum: int, _frame: object) -> None:
        self._received.set()

    def wait(self) -> None:
        """Block until SIGINT or SIGTERM has come (at once if one already has)."""
        while not self._received.is_set():
            select.select([self._reader], [], [])
            self._reader.recv(64)  # the signal numbers; the handler has run (or runs next)

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        for signum, handler in self._before.items():
            signal.signal(signum, handler)  # type: ignore[arg-type]
        signal.set_wakeup_fd(self._wakeup_before)
        self._reader.close()
        self._writer.close()


@contextlib.contextmanager
def uninterrupted(what: str) -> Iterator[None]:
    """Inside, SIGINT and SIGTERM only say that ``what`` is under way: a close that stops the arm,
    records the last trial and releases the rig and the database in order is never cut short half
    way (which would leave its objects to the interpreter's exit, in no order). Off the main
    thread, where no handler can be set, it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def note(signum: int, _frame: object) -> None:
        log.warning("%s: %s is under way (the arm is stopped first)", signal.Signals(signum).name,
                    what)

    before = {signum: signal.signal(signum, note) for signum in QUIT_SIGNALS}
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
