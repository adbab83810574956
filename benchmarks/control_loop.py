"""Control-loop speed: per-step compute time of filter + coupling + DMP, and deadline misses on the
wall clock with the mock arm.

    python benchmarks/control_loop.py [--seconds 12] [--trials 20]

Prints, for the step (eqs. 6-10 then 1-5): median and p99 in µs, against the uncoupled DMP step
measured in the same run on the same hand data (baseline) and against the 500 Hz period; then, for
125 Hz and 500 Hz real-time handovers of the perturbed scenario totalling at least --seconds, the
share of cycles that missed their deadline, the median and p99 start lateness, and the median and p99
whole-cycle compute time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from robot_io.config import ControllerConfig, LoopConfig
from robot_io.control.coupling import HandCoupling
from robot_io.control.dmp import DMP
from robot_io.control.trial import simulate_trial
from robot_io.hands.simulated_hand import Scenario, SimulatedHand
from robot_io.theta import Theta

THETA = Theta(a=5.0, delta=-0.2, k=15.0)


def step_times(config: ControllerConfig, trials: int) -> tuple[np.ndarray, np.ndarray]:
    """Per cycle: time of coupling.update + dmp.step, and of an uncoupled dmp.step (the baseline),
    interleaved so that both see the same machine state."""
    dt = 1.0 / 500
    start, goal = config.scene.point("robot_start"), config.scene.point("handover_point")
    coupled, uncoupled = [], []
    for seed in range(trials):
        hand = SimulatedHand(Scenario.PERTURBED, config.scene, config.hand, seed)
        dmp = DMP.from_minimum_jerk(start, goal, config.dmp)
        plain = DMP.from_minimum_jerk(start, goal, config.dmp)
        coupling = HandCoupling(THETA, goal, config.dmp, dt)
        coupling.reset(hand.latest(0.0).position)
        for i in range(int(hand.arrival_time / dt)):
            position = hand.latest(i * dt).position
            began = time.perf_counter()
            dmp.step(dt, coupling.update(position))
            coupled.append(time.perf_counter() - began)
            began = time.perf_counter()
            plain.step(dt)
            uncoupled.append(time.perf_counter() - began)
    return np.array(coupled) * 1e6, np.array(uncoupled) * 1e6


def realtime_figures(config: ControllerConfig, rate: int, seconds: float,
                     priority: bool = False) -> dict[str, float]:
    config = config.model_copy(update={"loop": LoopConfig(rate_hz=rate,
                                                          realtime_priority=priority)})
    cycles = misses = 0
    lateness, compute = [], []
    seed = 0
    while cycles < seconds * rate:
        record = simulate_trial(config, THETA, Scenario.PERTURBED, seed, realtime=True)
        assert record.summary.outcome == "completed", record.summary.reason
        cycles += record.summary.cycles
        misses += record.summary.deadline_misses
        lateness.append(record.samples["lateness_s"][1:])
        compute.append(record.samples["compute_s"][np.isfinite(record.samples["compute_s"])])
        seed += 1
    late, comp = np.concatenate(lateness) * 1e6, np.concatenate(compute) * 1e6
    return {"rate_hz": rate, "seconds": cycles / rate, "handovers": seed, "cycles": cycles,
            "missed": misses, "miss_share_pct": 100.0 * misses / cycles,
            "lateness_median_us": float(np.median(late)), "lateness_p99_us": float(np.percentile(late, 99)),
            "cycle_compute_median_us": float(np.median(comp)),
            "cycle_compute_p99_us": float(np.percentile(comp, 99))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=12.0, help="real-time handovers per rate [s]")
    parser.add_argument("--trials", type=int, default=20, help="perturbed trials for the step timing")
    parser.add_argument("--realtime-priority", action="store_true",
                        help="control thread under SCHED_FIFO (needs root or CAP_SYS_NICE)")
    args = parser.parse_args()
    config = ControllerConfig()

    steps, plain = step_times(config, args.trials)
    median, p99 = np.median(steps), np.percentile(steps, 99)
    base = np.median(plain)
    print(f"step (filter+coupling+DMP), {len(steps)} steps: median {median:.1f} µs, p99 {p99:.1f} µs "
          f"(goal p99 < 50 µs); p99 = {100 * p99 / 2000:.1f} % of the 500 Hz period")
    print(f"  baseline, uncoupled DMP step: median {base:.1f} µs, p99 {np.percentile(plain, 99):.1f} µs"
          f" -> coupled/uncoupled median ratio {median / base:.2f}")
    for rate in (125, 500):
        fig = realtime_figures(config, rate, args.seconds, args.realtime_priority)
        print(f"{rate} Hz real time, mock arm, {fig['seconds']:.1f} s in {fig['handovers']} handovers: "
              f"{fig['missed']} of {fig['cycles']} cycles missed their deadline "
              f"({fig['miss_share_pct']:.3f} %, goal < 0.5 % at 500 Hz); start lateness median "
              f"{fig['lateness_median_us']:.0f} µs, p99 {fig['lateness_p99_us']:.0f} µs; whole cycle "
              f"compute median {fig['cycle_compute_median_us']:.0f} µs, "
              f"p99 {fig['cycle_compute_p99_us']:.0f} µs")


if __name__ == "__main__":
    main()
