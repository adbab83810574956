"""CPU a learner's forkserver spends after the process that started it was killed during its preload:
now (app.learning.forkserver_preload: it dies with its parent) and as before (the same modules
imported without it, as ``PRELOAD`` had them).

A session process (a ``python -c`` that starts a session's learner, as ``run-session`` and ``serve``
do) is SIGKILLed as soon as its forkserver has torch's library mapped, i.e. inside the imports; the
forkserver's user + system time is then read from /proc until it has gone. The variants alternate
``--runs`` times; printed are the medians of the CPU seconds and of the lifetime after the kill, and
the ratio (before / now). Every kill of a session in its first seconds (a crash and restart, the
suite's kill tests) paid "before".

Usage: ``.venv/bin/python benchmarks/killed_forkserver.py [--runs 5]``
"""

from __future__ import annotations

import argparse
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))  # the suite's support package
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.processes import CLOCK_TICKS, cpu_seconds, forkserver_in_preload

SESSION = ("from app.learning import worker\n"
           "{patch}"
           "from app.learning.config import LearnerConfig\n"
           "from app.learning.models import ParameterBox\n"
           "worker.LearnerClient.for_session(LearnerConfig(box=ParameterBox.unit_cube(3)))\n"
           "import time; time.sleep(600)\n")
BEFORE = 'worker.PRELOAD = ["app.learning.learner", "torch.fx.experimental.symbolic_shapes"]\n'
def one_kill(before: bool) -> tuple[float, float]:
    """CPU seconds and seconds of life of the forkserver after its session's SIGKILL."""
    code = SESSION.format(patch=BEFORE if before else "")
    session = subprocess.Popen([sys.executable, "-c", code])
    forkserver = None
    while forkserver is None:
        if session.poll() is not None:
            raise SystemExit(f"the session ended (exit code {session.returncode}) before its "
                             "forkserver was seen importing torch")
        forkserver = forkserver_in_preload(session.pid)
        time.sleep(0.005)
    at_kill = cpu_seconds(forkserver) or 0.0
    session.send_signal(signal.SIGKILL)
    killed = time.monotonic()
    session.wait()
    last = at_kill
    while (now := cpu_seconds(forkserver)) is not None:
        last = now
        time.sleep(0.01)
    return last - at_kill, time.monotonic() - killed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    results: dict[bool, list[tuple[float, float]]] = {False: [], True: []}
    for _ in range(args.runs):  # alternated: a change of the machine's load touches both
        for before in (False, True):
            results[before].append(one_kill(before))
    for before, name in ((False, "now"), (True, "before")):
        cpu = statistics.median(r[0] for r in results[before])
        life = statistics.median(r[1] for r in results[before])
        print(f"{name:>6}: forkserver CPU after the kill {cpu:.2f} s, alive {life:.2f} s "
              f"(median of {args.runs})")
    now_cpu = statistics.median(r[0] for r in results[False])
    before_cpu = statistics.median(r[0] for r in results[True])
    ratio = (f"ratio {before_cpu / now_cpu:.1f}x" if now_cpu > 0 else
             f"now none within /proc's resolution, {1 / CLOCK_TICKS:.2f} s")
    print(f"saved per killed session {before_cpu - now_cpu:.2f} CPU-s ({ratio})")


if __name__ == "__main__":
    main()
