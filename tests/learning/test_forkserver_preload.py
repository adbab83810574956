"""A learner's forkserver dies with the process that started it while it imports the learner
(app.learning.forkserver_preload): a session killed in its first seconds leaves no forkserver that
goes on importing torch for nobody.

How the forkserver ended is read by a referee process (this file, run as a script) that makes itself
the child subreaper (``PR_SET_CHILD_SUBREAPER``): when the session's process dies, its orphans
become the referee's children, and the referee's ``waitpid`` says whether the forkserver was killed
(by its parent's death) or exited (after its imports, by finding its parent gone).
"""

from __future__ import annotations

import ctypes
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

#: ``prctl(2)`` option: orphaned descendants are reparented to this process, not to init.
PR_SET_CHILD_SUBREAPER = 36
#: A session's process as far as its learner goes: it starts one, which starts the forkserver.
SESSION = ("from app.learning.config import LearnerConfig\n"
           "from app.learning.models import ParameterBox\n"
           "from app.learning.worker import LearnerClient\n"
           "LearnerClient.for_session(LearnerConfig(box=ParameterBox.unit_cube(3)))\n"
           "import time; time.sleep(600)\n")
#: A ceiling for the forkserver to appear and start its imports (not a measurement).
CEILING_S = 120.0


def referee() -> None:
    """Start a session, SIGKILL it while its forkserver imports, print how the forkserver ended."""
    sys.path.insert(0, str(Path(__file__).parents[1]))  # run as a script: the suite's support
    from support.processes import forkserver_in_preload

    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
    session = subprocess.Popen([sys.executable, "-c", SESSION])
    deadline, forkserver = time.monotonic() + CEILING_S, None
    while forkserver is None:
        if session.poll() is not None or time.monotonic() > deadline:
            session.kill()
            sys.exit(f"no forkserver importing torch under pid {session.pid} within {CEILING_S} s "
                     f"(session exit code {session.poll()})")
        forkserver = forkserver_in_preload(session.pid)
        time.sleep(0.01)
    session.send_signal(signal.SIGKILL)  # the session's own process (Popen runs no shell)
    session.wait()
    _, status = os.waitpid(forkserver, 0)  # now this process's child
    print(json.dumps({"signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None,
                      "exit_code": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None}))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(2) is Linux's")
def test_a_forkserver_dies_with_its_session_while_it_imports():
    done = subprocess.run([sys.executable, __file__], capture_output=True, text=True,
                          timeout=CEILING_S * 2)
    assert done.returncode == 0, done.stderr
    ended = json.loads(done.stdout.strip().splitlines()[-1])
    # Before the fix: {"signal": None, "exit_code": 0}, the forkserver having imported everything.
    assert ended == {"signal": signal.SIGKILL, "exit_code": None}


if __name__ == "__main__":
    referee()
