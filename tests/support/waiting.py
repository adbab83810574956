"""Waiting for a state, never for time.

Every wait in the suite names the state it waits for and, when it gives up, says what it saw last.
The timeout is a ceiling for a hung system, not a measurement: it is far above what the state takes
on a loaded 2-core machine (two suites side by side, a CPU hog on one core), so a test that passes
idle passes loaded and fails only when the state never comes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

#: The default ceiling of a wait [s]: a state that has not come by then will not come.
CEILING_S = 60.0
#: How often a polled state is looked at [s] (a look costs a /proc read or a small query).
POLL_S = 0.02


class WaitTimeout(AssertionError):
    """A state did not come within its ceiling; the message names it and what was seen instead."""


def wait_for(check: Callable[[], T], what: str, timeout: float = CEILING_S,
             seen: Callable[[], object] | None = None, poll: float = POLL_S) -> T:
    """Poll ``check`` until it returns something truthy, and return that.

    ``what`` names the awaited state; ``seen`` describes what there is instead (page text, a log's
    tail, a process state), printed when the wait gives up after ``timeout`` seconds. An exception
    raised by ``check`` ends the wait at once (a dead process is not a slow one)."""
    deadline = time.monotonic() + timeout
    while True:
        if result := check():
            return result
        if time.monotonic() >= deadline:
            saw = "" if seen is None else f"; saw: {_describe(seen)}"
            raise WaitTimeout(f"gave up after {timeout:g} s waiting for {what}{saw}")
        time.sleep(poll)


def _describe(seen: Callable[[], object]) -> str:
    try:
        return str(seen())
    except Exception as exc:  # what was seen could not be read: say so, keep the timeout's message
        return f"<could not read: {exc!r}>"


def tail(text: str, chars: int = 2000) -> str:
    """The end of a log, for a wait's ``seen``."""
    return text if len(text) <= chars else "…" + text[-chars:]
