"""`.ci/timed.py`, through which `make test` runs pytest, counts the CPU time of every process the
run started, orphans included, and names the processes that outlive the run.

Before it became the run's subreaper, a process whose parent ended without waiting for it went to
init with its CPU time: Chromium's renderers, a killed server's rig and learner. A browser test
counted 9 of its 31 CPU-seconds, the whole suite about half of what kept both cores busy.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TIMED = ROOT / ".ci" / "timed.py"

#: A command whose only CPU is spent by an orphan: its child starts a grandchild and exits at once
#: without waiting for it; the grandchild burns CPU for ``BURN_S`` seconds of its own, writes how
#: much it used, and exits.
ORPHAN_BURNS = '''
import os, sys, time
if os.fork() == 0:
    if os.fork() == 0:
        while time.process_time() < {burn_s}:
            pass
        with open(sys.argv[1] + ".part", "w") as out:
            out.write(str(time.process_time()))
        os.rename(sys.argv[1] + ".part", sys.argv[1])
        os._exit(0)
    os._exit(0)
os.wait()
while not os.path.exists(sys.argv[1]):
    time.sleep(0.01)
'''
BURN_S = 1.0
#: A command that leaves an orphan running (for ten minutes) and exits.
ORPHAN_STAYS = '''
import os, time
if os.fork() == 0:
    if os.fork() == 0:
        time.sleep(600)
    os._exit(0)
os.wait()
'''
REPORT = re.compile(r"(\d+) s wall, (\d+) CPU-s \(")


def timed(folder: Path, *command: str) -> str:
    """timed.py's output for ``command``; into a file, not a pipe, which an orphan would hold open."""
    output = folder / "timed.out"
    with output.open("w") as out:
        code = subprocess.run([sys.executable, str(TIMED), *command], stdout=out,
                              stderr=subprocess.STDOUT, timeout=120).returncode
    assert code == 0, f"timed.py exited {code}:\n{output.read_text()}"
    return output.read_text()


def test_an_orphans_cpu_time_is_counted(tmp_path: Path) -> None:
    used_file = tmp_path / "used"
    out = timed(tmp_path, sys.executable, "-c", ORPHAN_BURNS.format(burn_s=BURN_S), str(used_file))
    used = float(used_file.read_text())
    report = REPORT.search(out)
    assert report, f"no report of the CPU time in:\n{out}"
    # Rounded to whole seconds: the orphan's BURN_S (1.0 s and a little more) is 1 or 2 CPU-s, the
    # rest of the run a fraction of one; uncounted, the run shows 0.
    assert int(report.group(2)) >= round(used), f"the orphan used {used:.2f} CPU-s; timed.py said:\n{out}"
    assert "outlived" not in out, out


def test_a_process_that_outlives_the_run_is_named(tmp_path: Path) -> None:
    """Slow on shared cores: after the command, timed.py gives its orphans 3 s to end, then runs the
    calibration loop (~3 CPU-s, longer on the wall clock while other tests hold the cores)."""
    out = timed(tmp_path, sys.executable, "-c", ORPHAN_STAYS)
    named = re.search(r"1 of its processes outlived it: (\d+) python", out)
    if named:
        os.kill(int(named.group(1)), signal.SIGKILL)
    assert named, f"the sleeping orphan is not named:\n{out}"
