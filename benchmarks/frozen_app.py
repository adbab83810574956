"""Seconds from freezing the application (SIGSTOP, as Ctrl-Z does) mid-reach to the controller's
last servoL, over repeated runs (issue 25, item 1: the rig sees a stopped application in its
process state, looking every HEARTBEAT_S / 2 while nothing comes).

Each run is ``handover run-session --auto`` on the stand-in UR (real RTDE through ur_rtde), frozen
once 25 servo targets have reached the controller; the time is the stand-in's stamp of its last
servoL minus the moment of the SIGSTOP, both on this machine's monotonic clock. Baseline of the same
run: a session that is not frozen, from the same moment (25 targets) to the last servoL of that
trial's stream, which is how long a frozen application's arm streamed on before the rig watched its
application (to H, then holding there until the release timed out).

Usage: ``.venv/bin/python benchmarks/frozen_app.py [--runs 10]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
# the checkout before tests/, whose robot_io/ folder would pass for the robot_io package
sys.path.insert(0, str(Path(__file__).parents[1]))

from support.frozen import end, freeze_mid_reach, reach_under_way, start_session
from support.ur import SERVO_STOP, commands, servo_targets, standin
from support.waiting import CEILING_S, wait_for

from robot_io.rig.messages import HEARTBEAT_S


def frozen_run() -> tuple[float, int]:
    """(seconds from SIGSTOP to the last servoL, servo targets after the SIGSTOP) of one run."""
    with tempfile.TemporaryDirectory() as folder, standin() as ur:
        run = start_session(Path(folder), ur)
        try:
            frozen = freeze_mid_reach(run, ur, Path(folder))
        finally:
            end(run)
    return frozen.last_servo_s, frozen.targets_after


def unfrozen_run() -> float:
    """Seconds from the same moment to the last servoL of the first trial's stream, unfrozen."""
    with tempfile.TemporaryDirectory() as folder, standin() as ur:
        run = start_session(Path(folder), ur)
        try:
            at = reach_under_way(run, ur, Path(folder))
            # the first trial's stream ends with servoStop: its last servoL is just before it
            wait_for(lambda: SERVO_STOP in commands(ur.control), "the first trial's servoStop",
                     timeout=CEILING_S * 2)
            targets = servo_targets(ur.control)
        finally:
            end(run)
    return targets[-1][0] - at


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    args = parser.parse_args()
    runs = [frozen_run() for _ in range(args.runs)]
    seconds = [s for s, _ in runs]
    targets = [n for _, n in runs]
    baseline = unfrozen_run()
    print(f"SIGSTOP → last servoL, {args.runs} runs: median {statistics.median(seconds):.3f} s, "
          f"max {max(seconds):.3f} s (the rig looks every {HEARTBEAT_S / 2:g} s)")
    print(f"servo targets after the SIGSTOP: median {statistics.median(targets):g}, "
          f"max {max(targets)} (125 per second)")
    print(f"baseline, not frozen: the stream went on {baseline:.3f} s from the same moment "
          f"(ratio to the frozen median: {baseline / statistics.median(seconds):.0f}×)")
    print("runs [s]:", " ".join(f"{s:.3f}" for s in seconds))


if __name__ == "__main__":
    main()
