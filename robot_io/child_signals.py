"""What a child process of the application does with its terminal's Ctrl-C and with its parent's end.

**Ctrl-C.** A terminal sends SIGINT to its whole foreground process group: the application and the
children it starts (the rig, the learner's forkserver and workers, the hand publisher). Each child
ignores it (the application acts on Ctrl-C: it stops the arm through the rig, then ends them), but
a child can ignore it only once its own code runs. A child started with ``spawn`` first imports
``site``, re-imports the application's main module and unpickles its arguments (pydantic, numpy):
a Ctrl-C in that second or two was a ``KeyboardInterrupt`` traceback from the child. So the parent
starts a child with SIGINT *blocked* in the starting thread (:func:`interrupts_held`; fork and exec
keep a thread's signal mask), and the child, once it ignores SIGINT, unblocks it
(:func:`ignore_interrupts`): a Ctrl-C that came meanwhile waited, and is dropped.

**The parent's end.** :func:`ends_with_its_parent`: the kernel kills the calling process when the
*thread* that started it ends (Linux's ``PR_SET_PDEATHSIG``; elsewhere nothing). For a child whose
parent may die without ending it (a SIGKILL), and which must not outlive it: the learner's
forkserver while it imports, ur_rtde's control worker while it holds the arm's control connection.
"""

from __future__ import annotations

import ctypes
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing import resource_tracker

#: ``prctl(2)`` option: the signal this process gets when its parent thread ends (0: none).
PR_SET_PDEATHSIG = 1
#: What a child of the application leaves to it (see the module's docstring).
HELD = frozenset({signal.SIGINT})


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Children that the calling thread starts meanwhile begin with SIGINT blocked, until they call
    :func:`ignore_interrupts`. The calling thread's own SIGINT waits meanwhile (the application's
    other threads still take it); its mask is restored after.

    CPython's resource tracker (which every ``spawn`` or ``forkserver`` start makes sure runs) is
    started the same way (bpo-33613), but then *unblocks* SIGINT in the starting thread rather
    than restoring its mask: it is started first, outside the hold."""
    resource_tracker.ensure_running()
    before = signal.pthread_sigmask(signal.SIG_BLOCK, HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def ignore_interrupts() -> None:
    """In a child of the application, first thing: ignore SIGINT, then unblock it (a Ctrl-C that came
    while the child started, held by :func:`interrupts_held`, is dropped)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, HELD)


def _set_parent_death_signal(signum: int) -> None:
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signum, 0, 0, 0)


@contextmanager
def ends_with_its_parent() -> Iterator[None]:
    """Inside: this process is SIGKILLed when the thread that started it ends (on Linux; elsewhere
    nothing). A parent that ended before this was set is not noticed: check ``os.getppid()``."""
    _set_parent_death_signal(signal.SIGKILL)
    try:
        yield
    finally:
        _set_parent_death_signal(0)
