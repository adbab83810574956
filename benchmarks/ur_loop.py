"""Control-loop timing against the stand-in UR controller with ur_rtde's real client.

    python benchmarks/ur_loop.py [--seconds 10] [--host-base 127.0.0.12]

For a CB-series stand-in (125 Hz) and an e-Series stand-in (500 Hz), each in its own process on its
own loopback address, runs real-time handovers (perturbed scenario) totalling at least --seconds and
prints: the loop's cycle period (median, p99) and deadline misses, and the period between servoL
targets as the controller received them (median, p99). Baseline: the nominal period (8 ms, 2 ms);
the same loop with the mock arm is in benchmarks/control_loop.py. The machine is shared: read p99
against the load it was run under (printed).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

import numpy as np

from robot_io.arms.ur_arm import URArm
from robot_io.config import ControllerConfig
from robot_io.devices import arm_trial
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.standins.ur.control import ControlClient
from robot_io.theta import Theta

THETA = Theta(a=5.0, delta=-0.2, k=15.0)
SERVOL = 24


def figures(series: str, host: str, seconds: float) -> dict[str, float]:
    config = ControllerConfig()
    config = config.model_copy(update={"ur": config.ur.model_copy(update={"host": host})})
    standin = subprocess.Popen([sys.executable, "-m", "robot_io.standins.ur", "--host", host,
                                "--series", series, "--exit-with-stdin"],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        standin.stdout.readline()
        control = ControlClient(host)
        arm = URArm(config.ur, config.safety)
        periods, misses, cycles, seed = [], 0, 0, 0
        try:
            while cycles < seconds * arm.rate_hz:
                hand = SimulatedHand(Scenario.PERTURBED, config.scene, config.hand, seed)
                record = arm_trial(config, THETA, hand, arm)
                assert record.summary.outcome == "completed", record.summary.reason
                periods.append(np.diff(record.samples["t"]))
                misses += record.summary.deadline_misses
                cycles += record.summary.cycles
                seed += 1
            rate = arm.rate_hz
        finally:
            arm.close()
        received = np.array([t for t, command, _ in control("received")["received"] if command == SERVOL])
        control.close()
    finally:
        standin.stdin.close()
        standin.wait(10)
    gaps = np.diff(received)
    gaps = gaps[gaps < 0.5]  # not the pause between handovers
    loop = np.concatenate(periods) * 1e3
    return {"rate": rate, "handovers": seed, "cycles": cycles, "misses": misses,
            "loop_median_ms": float(np.median(loop)), "loop_p99_ms": float(np.percentile(loop, 99)),
            "rx_median_ms": float(np.median(gaps) * 1e3), "rx_p99_ms": float(np.percentile(gaps, 99) * 1e3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="real-time handovers per rate [s]")
    parser.add_argument("--host-base", default="127.0.0.12", help="stand-ins on <base>5 and <base>6")
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    for series, last in (("cb3", "5"), ("e", "6")):
        f = figures(series, args.host_base + last, args.seconds)
        nominal = 1e3 / f["rate"]
        print(f"{f['rate']} Hz ({'CB-series' if series == 'cb3' else 'e-Series'} stand-in), "
              f"{f['handovers']} handovers, {f['cycles']} cycles: loop period median "
              f"{f['loop_median_ms']:.3f} ms, p99 {f['loop_p99_ms']:.3f} ms (nominal {nominal:g} ms); "
              f"{f['misses']} deadline misses ({100 * f['misses'] / f['cycles']:.2f} %); servoL as "
              f"received by the controller: median {f['rx_median_ms']:.3f} ms, p99 {f['rx_p99_ms']:.3f} ms")


if __name__ == "__main__":
    main()
