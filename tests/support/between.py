"""Make a race between two threads happen, rather than hope for it: hold one thread at a chosen line
of a chosen function, once, while the test acts from its own thread, then let it go on.

A trace function is per thread: install :meth:`Between.tracing` while the thread to hold is started
(``threading.settrace`` reaches the threads started after it), then :meth:`Between.arm` it when the
next pass through the line is the one to hold.
"""

from __future__ import annotations

import contextlib
import inspect
import threading
from collections.abc import Callable, Iterator
from types import FrameType

from support.waiting import CEILING_S


class Between:
    """Holds the first thread that reaches the line of ``function`` containing ``marker`` after
    :meth:`arm` (and whose frame ``when`` accepts) until :meth:`release`. Only calls entered after
    ``arm`` are watched."""

    def __init__(self, function: Callable, marker: str) -> None:
        self.code = function.__code__
        lines, first = inspect.getsourcelines(function)
        self.line = first + next(i for i, text in enumerate(lines) if marker in text)
        self.when: Callable[[FrameType], bool] | None = None
        self.holding, self.released = threading.Event(), threading.Event()

    @contextlib.contextmanager
    def tracing(self) -> Iterator[None]:
        """Threads started inside this block are watched."""
        threading.settrace(self.trace)
        try:
            yield
        finally:
            threading.settrace(None)

    def arm(self, when: Callable[[FrameType], bool] = lambda frame: True) -> None:
        self.when = when

    def trace(self, frame: FrameType, kind: str, arg: object):
        if kind == "call" and frame.f_code is self.code and self.when is not None:
            return self._line
        return None

    def _line(self, frame: FrameType, kind: str, arg: object):
        when = self.when
        if kind == "line" and frame.f_lineno == self.line and when is not None and when(frame):
            self.when = None  # once
            self.holding.set()
            self.released.wait(CEILING_S)  # a ceiling for a test that failed before releasing
        return self._line

    def release(self) -> None:
        self.released.set()
