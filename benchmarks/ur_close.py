"""How long the UR backend takes to let go of the controller, against the stand-in.

    python benchmarks/ur_close.py [--closes 5]

Connects ``URArm`` to a stand-in CB-series controller (tests/support/ur.py: a free loopback address,
always ended) and closes it ``--closes`` times; prints the
median of ``URArm.close()`` and, as the baseline of the same run, the median of releasing ur_rtde's
receive interface as the backend did before (``disconnect()``, then the drop, whose destructor
disconnects again) and of dropping it alone (what ``close`` does now). A rig's close is part of
every participant switch and shutdown, and the application kills a rig slow to exit.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.ur import standin

from robot_io.arms.ur_arm import URArm
from robot_io.config import ControllerConfig


def timed(action: Callable[[], None]) -> float:
    began = time.perf_counter()
    action()
    return time.perf_counter() - began


def receive_release(host: str, disconnect_first: bool) -> float:
    """Seconds to release one connected RTDEReceiveInterface (the drop: its destructor runs)."""
    import rtde_receive

    holder = [rtde_receive.RTDEReceiveInterface(host, -1.0, ["timestamp", "actual_TCP_pose"])]

    def release() -> None:
        if disconnect_first:
            holder[0].disconnect()
        holder.clear()

    return timed(release)


def report(closes: int) -> None:
    """Start a stand-in, time ``closes`` closes of each kind, print the medians."""
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with standin() as ur:
        config = ControllerConfig()
        config = config.model_copy(update={"ur": config.ur.model_copy(update={"host": ur.host})})
        arm_closes = []
        for _ in range(closes):
            arm = URArm(config.ur, config.safety)
            arm_closes.append(timed(arm.close))
        before = [receive_release(ur.host, disconnect_first=True) for _ in range(closes)]
        now = [receive_release(ur.host, disconnect_first=False) for _ in range(closes)]
    median_before, median_now = statistics.median(before), statistics.median(now)
    print(f"URArm.close(): median {statistics.median(arm_closes):.3f} s over {closes} closes\n"
          f"the receive interface released by disconnect() then the drop (before): median "
          f"{median_before:.3f} s; by the drop alone (now): median {median_now:.3f} s; "
          f"ratio {median_before / median_now:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--closes", type=int, default=5, help="connect-close cycles of each kind")
    report(**vars(parser.parse_args()))


if __name__ == "__main__":
    main()
