"""What a learner's forkserver imports before it forks the first learner (``worker.PRELOAD``), for
as long as the process that started it is alive.

The imports take ~4.5 CPU-seconds (torch, GPyTorch, BoTorch and, for the first GP fit, torch's
symbolic shapes with sympy). A forkserver notices that its parent has gone only in its serving loop,
after them: a ``run-session`` or ``serve`` killed (or quickly ended) in its first seconds used to
leave a forkserver that finished every import for nobody, on the CPU that the restarted session
needed. Here the kernel kills the forkserver with its parent (Linux's ``PR_SET_PDEATHSIG``) while it
imports, and no longer once it serves: the signal follows the parent *thread*, which waits in
``Process.start()`` until the forkserver has imported and forked, but may end afterwards while the
server must stay. A parent that dies in the instant before the signal is set (the interpreter's own
start) leaves a forkserver that imports as before; it ends as soon as it reaches its loop.
"""

from __future__ import annotations

import ctypes
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager

#: ``prctl(2)`` option: the signal this process gets when its parent thread ends (0: none).
PR_SET_PDEATHSIG = 1


def _set_parent_death_signal(signum: int) -> None:
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signum, 0, 0, 0)


@contextmanager
def ends_with_its_parent() -> Iterator[None]:
    """Inside: this process is SIGKILLed when its parent ends (on Linux; elsewhere nothing)."""
    _set_parent_death_signal(signal.SIGKILL)
    try:
        yield
    finally:
        _set_parent_death_signal(0)


# Ctrl-C in the application's terminal reaches its whole process group, this server too: while it
# imports, a KeyboardInterrupt killed it and the session's learner start failed with "unexpected
# EOF" (a traceback at every early Ctrl-C). multiprocessing ignores SIGINT here only after the
# imports; from now on, and in the learners forked from here, the application ends them.
signal.signal(signal.SIGINT, signal.SIG_IGN)

with ends_with_its_parent():
    import torch.fx.experimental.symbolic_shapes  # noqa: F401  (torch.broadcast_shapes, first fit)

    import app.learning.learner  # noqa: F401
