"""The stand-in UR controller's own load: CPU seconds per wall second of its controller cycle while
one ur_rtde receive interface reads its RTDE outputs (as a rehearsal's rig does), median of repeated
windows. Every rehearsal, UR test and ``serve --rehearse`` runs one; on a 2-core machine what it
burns is taken from the suite.

Baseline of the same run: the same stand-in with no client (its cycle only, no output package).
Measured per thread from /proc: the CPU share of the stand-in's busiest thread, its controller cycle.

Usage: ``.venv/bin/python benchmarks/standin_load.py [--series cb3|e] [--windows 5] [--seconds 3]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.ur import standin

TICKS = os.sysconf("SC_CLK_TCK")


def thread_cpu(pid: int) -> dict[str, float]:
    """CPU seconds (user + system) of every thread of ``pid``, by thread id."""
    cpu = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{tid}/stat") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
        cpu[tid] = (int(fields[11]) + int(fields[12])) / TICKS
    return cpu


def busiest_share(pid: int, seconds: float) -> float:
    """The largest CPU share (CPU-s per s) of one thread of ``pid`` over ``seconds``."""
    before, began = thread_cpu(pid), time.monotonic()
    time.sleep(seconds)  # the measurement window
    after, elapsed = thread_cpu(pid), time.monotonic() - began
    return max(after[tid] - before.get(tid, 0.0) for tid in after) / elapsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--series", choices=("cb3", "e"), default="cb3")
    parser.add_argument("--windows", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    import rtde_receive

    with standin(args.series) as ur:
        pid = ur.process.pid
        idle = [busiest_share(pid, args.seconds) for _ in range(args.windows)]
        receive = rtde_receive.RTDEReceiveInterface(ur.host)
        try:
            read = [busiest_share(pid, args.seconds) for _ in range(args.windows)]
        finally:
            receive.disconnect()
    print(f"stand-in {args.series}, controller cycle's CPU share, median of {args.windows} windows "
          f"of {args.seconds:g} s:")
    print(f"  one ur_rtde receive client: {statistics.median(read):.3f} CPU-s/s "
          f"(min {min(read):.3f}, max {max(read):.3f})")
    print(f"  baseline, no client:        {statistics.median(idle):.3f} CPU-s/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
