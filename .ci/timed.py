"""Run a command; then print its wall time, its CPU time and the calibration loop's CPU time.

    python .ci/timed.py pytest -n 3 ...

`make test` runs pytest through it. The CPU time is the user + system time of the command and of
every process it started, however deep: this process is the run's child subreaper (Linux's
``PR_SET_CHILD_SUBREAPER``), so a process whose parent ended without waiting for it (Chromium's
renderers and its zygote, a killed server's rig and learner processes) is handed here and reaped,
and its time is counted. Without it the kernel hands such a process to init, and its time was lost:
a browser test counted 9 of its 31 CPU-seconds, the suite 803 of the ~1,560 that kept both cores
busy. The calibration loop (``s=0; for i in range(20_000_000): s+=i*i``, 3.1 CPU-s on the reference
machine) says how fast this machine was at the time, so that figures from different machines and
moments can be compared. A process of the run still alive when the command ends is named (a leak).
The command's exit code is this script's.
"""

from __future__ import annotations

import ctypes
import os
import resource
import signal
import subprocess
import sys
import time

import psutil

#: The issue-44 calibration loop: its CPU-seconds are quoted with every figure of the suite's time.
CALIBRATION = "s=0\nfor i in range(20_000_000): s+=i*i"
#: ``prctl(2)`` option: orphaned descendants are re-parented to this process instead of init.
PR_SET_CHILD_SUBREAPER = 36
#: How long the orphans of an ended command may take to end before they are named as leaks [s].
ORPHANS_CEILING_S = 3.0


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def become_subreaper() -> bool:
    """Make this process the subreaper of everything it starts (Linux); False elsewhere."""
    if not sys.platform.startswith("linux"):
        return False
    return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0


def reap(until: int) -> int:
    """Wait for every child, orphans handed here included, until ``until`` ends; its exit code."""
    while True:
        pid, status = os.waitpid(-1, 0)
        if pid == until:
            return os.waitstatus_to_exitcode(status)


def reap_ended() -> bool:
    """Reap the children that have ended; True when no child is left."""
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return True
        if pid == 0:
            return False


def reap_orphans(ceiling_s: float = ORPHANS_CEILING_S) -> None:
    """Reap the orphans that end with the command (a browser's renderers die after it), until none
    is left or for ``ceiling_s``; those alive then are the run's leaks."""
    deadline = time.monotonic() + ceiling_s
    while not reap_ended() and time.monotonic() < deadline:
        time.sleep(0.05)


def survivors() -> list[str]:
    """The processes still handed to this one: ``pid name`` of each child alive now."""
    return [f"{child.pid} {child.name()}" for child in psutil.Process().children()]


def main() -> int:
    command = sys.argv[1:]
    counted = become_subreaper()
    # Ctrl-C reaches the command from the terminal; this process waits for it to end and reports.
    signal.signal(signal.SIGINT, lambda signum, frame: None)
    began, cpu_before = time.monotonic(), children_cpu()
    process = subprocess.Popen(command)
    code = process.returncode = reap(process.pid)
    wall = time.monotonic() - began
    if counted:
        reap_orphans()
    cpu = children_cpu() - cpu_before
    left = survivors() if counted else []
    subprocess.run([sys.executable, "-c", CALIBRATION], check=True)
    calibration = children_cpu() - cpu_before - cpu
    scope = "with every process it started" if counted else "with the processes it waited for"
    print(f"\n{command[0].rsplit('/', 1)[-1]}: {wall:.0f} s wall, {cpu:.0f} CPU-s ({scope}); "
          f"calibration loop {calibration:.2f} CPU-s (3.1 on the reference machine); "
          f"exit code {code}", flush=True)
    if left:
        print(f"{len(left)} of its processes outlived it: {', '.join(left)}", flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
