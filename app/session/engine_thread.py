"""The engine thread: the one thread on which the open session's engine and its SQLite store are
touched, one job at a time (docs/architecture.md, "Threads and who owns what", rule 1).

Jobs come from the screens, the session worker and the rig's reader; each waits for its result
(:meth:`EngineThread.call`) or leaves it to run in order (:meth:`EngineThread.post`). Once
:meth:`EngineThread.close` has begun, a job is refused with :class:`SessionClosed` (a
:class:`~app.protocol.errors.RefusedAction`, which every caller already handles), never with the
executor's ``RuntimeError``: a thread that is still finishing its own work when the session closes
ends quietly, with nothing printed.

The rule that the engine thread never publishes (rule 4: a screen may hold the publishing lock while
it waits for this thread) is checked, not only written: :meth:`EngineThread.forbid` raises
:class:`WrongThread`, naming the thread, when it is called on the engine thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

from app.protocol.errors import RefusedAction

T = TypeVar("T")

#: What a job sent after the close is refused with.
CLOSED = "the session is closed"


class SessionClosed(RefusedAction):
    """A job came after the session closed: nothing was done."""


class WrongThread(AssertionError):
    """Code ran on a thread that must not run it (a deadlock waiting to happen); raised even under
    ``python -O``."""


class EngineThread:
    """A single worker thread, created here and ended by :meth:`close` (the session runner owns it)."""

    def __init__(self) -> None:
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="engine")
        self._ident = self._executor.submit(threading.get_ident).result()
        self._closed = threading.Event()

    def on_it(self) -> bool:
        """Whether the calling thread is the engine thread."""
        return threading.get_ident() == self._ident

    def forbid(self, what: str) -> None:
        """Raise :class:`WrongThread` if called on the engine thread: ``what`` may wait for a lock
        that a thread waiting for the engine thread holds."""
        if self.on_it():
            raise WrongThread(f"{what} on the engine thread ({threading.current_thread().name}): it "
                              "may wait for a thread that waits for the engine thread; do it after "
                              "the job returns, on the caller's thread (docs/architecture.md, rule 4)")

    def call(self, job: Callable[[], T]) -> T:
        """Run ``job`` on the engine thread and return its result (or raise its exception); on the
        engine thread itself it runs at once."""
        if self.on_it():
            return job()
        return self._submit(job).result()

    def post(self, job: Callable[[], object]) -> None:
        """Queue ``job`` on the engine thread without waiting for it."""
        self._submit(job)

    def _submit(self, job: Callable[[], T]) -> Future[T]:
        if self._closed.is_set():
            raise SessionClosed(CLOSED)
        try:
            return self._executor.submit(job)
        except RuntimeError as exc:  # closed between the check and the submit
            raise SessionClosed(CLOSED) from exc

    @property
    def closed(self) -> bool:
        return self._closed.is_set()

    def close(self) -> None:
        """Refuse new jobs, let the queued ones finish, and end the thread (not from itself)."""
        self.forbid("closing the engine thread")
        self._closed.set()
        self._executor.shutdown(wait=True)
