"""Run a command; then print its wall time, its CPU time and the calibration loop's CPU time.

    python .ci/timed.py pytest -n 3 ...

`make test` runs pytest through it. The CPU time is the user + system time of the command and of
every process it started and waited for (on two cores the suite's wall time follows it); the
calibration loop (``s=0; for i in range(20_000_000): s+=i*i``, 3.1 CPU-s on the reference machine)
says how fast this machine was at the time, so that figures from different machines and moments
can be compared. The command's exit code is this script's.
"""

from __future__ import annotations

import resource
import subprocess
import sys
import time

#: The issue-44 calibration loop: its CPU-seconds are quoted with every figure of the suite's time.
CALIBRATION = "s=0\nfor i in range(20_000_000): s+=i*i"


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> int:
    command = sys.argv[1:]
    began, cpu_before = time.monotonic(), children_cpu()
    code = subprocess.call(command)
    wall, cpu = time.monotonic() - began, children_cpu() - cpu_before
    subprocess.run([sys.executable, "-c", CALIBRATION], check=True)
    calibration = children_cpu() - cpu_before - cpu
    print(f"\n{command[0].rsplit('/', 1)[-1]}: {wall:.0f} s wall, {cpu:.0f} CPU-s "
          f"(with the processes it waited for); calibration loop {calibration:.2f} CPU-s "
          f"(3.1 on the reference machine); exit code {code}", flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
