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

from robot_io.child_signals import ends_with_its_parent, ignore_interrupts

# Ctrl-C in the application's terminal reaches its whole process group, this server too: while it
# imported, a KeyboardInterrupt killed it and the session's learner start failed with "unexpected
# EOF" (a traceback at every early Ctrl-C). Its starter held SIGINT until here (interrupts_held);
# from now on, and in the learners forked from here, the application ends them.
ignore_interrupts()

with ends_with_its_parent():
    import torch.fx.experimental.symbolic_shapes  # noqa: F401  (torch.broadcast_shapes, first fit)

    import app.learning.learner  # noqa: F401
